#include "tools/cli_args.h"

#include <filesystem>

#include "absl/strings/str_cat.h"

namespace ss::cli {

std::string Args::get(const std::string& name, const std::string& fallback) const {
  auto it = values.find(name);
  return it == values.end() ? fallback : it->second;
}

absl::StatusOr<Args> parse_args(int argc, char** argv, int first, const std::set<std::string>& value_flags,
                                const std::set<std::string>& switch_flags) {
  Args args;
  for (int i = first; i < argc; ++i) {
    std::string a = argv[i];
    if (a.rfind("--", 0) != 0 || a == "--") {
      args.positional.push_back(a);
      continue;
    }
    std::string name = a.substr(2), value;
    bool inline_value = false;
    if (auto eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      inline_value = true;
    }
    if (switch_flags.count(name)) {
      if (inline_value) return absl::InvalidArgumentError("--" + name + " takes no value");
      args.switches.insert(name);
    } else if (value_flags.count(name)) {
      if (!inline_value) {
        if (i + 1 >= argc) return absl::InvalidArgumentError("--" + name + " needs a value");
        value = argv[++i];
      }
      args.values[name] = value;
    } else {
      return absl::InvalidArgumentError("unknown flag --" + name);
    }
  }
  return args;
}

absl::StatusOr<std::string> model_path(const Args& args) {
  if (args.has("model")) return args.get("model");
  std::error_code ec;
  if (std::filesystem::exists(kDefaultModel, ec)) return std::string(kDefaultModel);
  return absl::NotFoundError(absl::StrCat("no --model given and no default model at ", kDefaultModel,
                                          " (none ships until its training run ends: models/MODEL_CARD.md)"));
}

}  // namespace ss::cli
