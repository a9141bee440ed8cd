#include "common/command_line.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>

#include "absl/flags/reflection.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace ss::cli {
namespace {

using FlagTable = std::map<std::string, absl::CommandLineFlag*>;  // by the name typed after "--"

// The command's flags: those defined in its file (without its prefix) and the shared ones it lists.
FlagTable flags_of(const Command& command) {
  // "scenestreamer dataset sumo": dataset_sumo_; the program itself ("scenestreamer-train"): none.
  const size_t space = command.name.find(' ');
  const std::string prefix =
      space == std::string::npos
          ? ""
          : absl::StrCat(absl::StrReplaceAll(command.name.substr(space + 1), {{" ", "_"}, {"-", "_"}}), "_");
  FlagTable table;
  for (const auto& [name, flag] : absl::GetAllFlags()) {
    absl::string_view typed = name;
    // Abseil's Filename() is __FILE__ without its leading slashes.
    if (absl::EndsWith(command.file, flag->Filename())) {
      absl::ConsumePrefix(&typed, prefix);
    } else if (std::find(command.shared.begin(), command.shared.end(), flag) == command.shared.end()) {
      continue;
    }
    if (!table.emplace(absl::StrReplaceAll(typed, {{"_", "-"}}), flag).second) {
      std::fprintf(stderr, "%s: two flags are --%s (a programming error)\n", command.name.c_str(),
                   std::string(typed).c_str());
      std::abort();
    }
  }
  return table;
}

// Words of `text` in lines of at most `width` characters, each indented by `indent` spaces.
std::string wrap(const std::string& text, int indent, size_t width) {
  std::string out, line;
  for (absl::string_view word : absl::StrSplit(text, ' ', absl::SkipEmpty())) {
    if (!line.empty() && line.size() + 1 + word.size() > width - indent) {
      absl::StrAppend(&out, std::string(indent, ' '), line, "\n");
      line.clear();
    }
    absl::StrAppend(&line, line.empty() ? "" : " ", word);
  }
  if (!line.empty()) absl::StrAppend(&out, std::string(indent, ' '), line, "\n");
  return out;
}

std::string help_text(absl::string_view usage, const FlagTable& flags) {
  std::string text = absl::StrCat(usage, "\nflags:\n");
  for (const auto& [name, flag] : flags) {
    std::string value = flag->DefaultValue();
    if (flag->IsOfType<std::string>()) value = absl::StrCat("\"", value, "\"");
    absl::StrAppend(&text, "  --", name, " (default: ", value, ")\n", wrap(flag->Help(), 6, 116));
  }
  return text;
}

void print_help(const Command& command, const FlagTable& flags) {
  std::fputs(help_text(command.usage, flags).c_str(), stdout);
}

// Whether `path` is `dir` or inside it (both made absolute and normal first; no file needs to exist).
bool is_within(const std::filesystem::path& path, const std::filesystem::path& dir) {
  std::error_code ec;
  const std::filesystem::path p = std::filesystem::weakly_canonical(path, ec);
  if (ec) return false;
  const std::filesystem::path d = std::filesystem::weakly_canonical(dir, ec);
  if (ec) return false;
  auto pi = p.begin();
  for (auto di = d.begin(); di != d.end(); ++di, ++pi) {
    if (di->empty()) continue;  // a trailing slash
    if (pi == p.end() || *pi != *di) return false;
  }
  return true;
}

}  // namespace

std::optional<int> parse_command(const Command& command, int argc, char** argv, CommandLine* line) {
  const FlagTable flags = flags_of(command);
  for (int i = 1; i < argc; ++i) {
    const absl::string_view arg = argv[i];
    if (arg == "--") {
      line->positional_.insert(line->positional_.end(), argv + i + 1, argv + argc);
      break;
    }
    if (!absl::StartsWith(arg, "--")) {
      line->positional_.emplace_back(arg);
      continue;
    }
    const size_t eq = arg.find('=');
    const std::string name(arg.substr(2, eq == absl::string_view::npos ? absl::string_view::npos : eq - 2));
    if (name == "help" && eq == absl::string_view::npos) {
      print_help(command, flags);
      return 0;
    }
    const auto it = flags.find(name);
    if (it == flags.end()) return usage_error(command, absl::StrCat("unknown flag --", name));
    absl::CommandLineFlag* flag = it->second;
    std::string value;
    if (eq != absl::string_view::npos) value = std::string(arg.substr(eq + 1));
    else if (flag->IsOfType<bool>()) value = "true";
    else if (i + 1 < argc) value = argv[++i];
    else return usage_error(command, absl::StrCat("--", name, " needs a value"));
    if (std::string error; !flag->ParseFrom(value, &error)) return usage_error(command, absl::StrCat("--", name, ": ", error));
    line->given_[flag] = absl::StrCat("--", name);
  }
  if (!command.positional && !line->positional_.empty())
    return usage_error(command, absl::StrCat("unexpected argument '", line->positional_[0], "'"));
  return std::nullopt;
}

std::string CommandLine::first_given(std::initializer_list<const absl::CommandLineFlag*> flags) const {
  for (const absl::CommandLineFlag* f : flags)
    if (auto it = given_.find(f); it != given_.end()) return it->second;
  return "";
}

int usage_error(const Command& command, absl::string_view message) {
  std::fprintf(stderr, "%s: %s\n(`%s --help` shows its usage and flags)\n", command.name.c_str(),
               std::string(message).c_str(), command.name.c_str());
  return 2;
}

std::string file_flags_help(absl::string_view usage, absl::string_view file) {
  FlagTable table;
  for (const auto& [name, flag] : absl::GetAllFlags())
    // Abseil's Filename() is __FILE__ without its leading slashes.
    if (absl::EndsWith(file, flag->Filename())) table.emplace(std::string(name), flag);
  return help_text(usage, table);
}

absl::StatusOr<std::string> bundled_dir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return absl::NotFoundError(absl::StrCat("cannot find the bundled files: /proc/self/exe: ", ec.message()));
  // Installed: P/bin/<program> and P/share/scenestreamer (the install rules in CMakeLists.txt).
  const std::filesystem::path installed = exe.parent_path().parent_path() / "share" / "scenestreamer";
  if (std::filesystem::is_directory(installed, ec)) return installed.lexically_normal().string();
  // In the build tree: the source tree it was configured from (compiled in by tools/CMakeLists.txt).
  if (is_within(exe, SS_BUILD_DIR) && std::filesystem::is_directory(SS_SOURCE_DIR, ec)) return std::string(SS_SOURCE_DIR);
  return absl::NotFoundError(absl::StrCat("no bundled files for ", exe.string(), ": no ",
                                          installed.lexically_normal().string(),
                                          " (where `cmake --install` puts them beside bin/), and the program is not "
                                          "in its build tree (", SS_BUILD_DIR, ")"));
}

}  // namespace ss::cli
