// The command line of one subcommand (of `scenestreamer` or `scenestreamer-train`), on Abseil flags.
//
// A command's own flags are the ABSL_FLAGs defined in its source file; flags that several commands take are defined
// once (tools/shared_flags.h) and each command lists the ones it takes. Every other flag of the program, another
// command's included, is refused: a command never quietly takes a flag meant for another.
//
// Abseil holds one flag of each name per program, so when two commands give a name different types or defaults
// (bench's --steps is 30 timed steps, simulate's runs to the scenario's end), each defines it with its command's
// words first: bench_steps is bench's --steps, dataset_sumo_radius is `dataset sumo`'s --radius. The command line
// spells names with dashes (--top-p is top_p), as the tools always have.
//
// The arguments are split here rather than by absl::ParseCommandLine, which in Debian's Abseil (20220623) exits 1 on
// a bad flag (usage errors exit 2 here), accepts every flag of the program, prints a warning for `--out -`, and keeps
// IsSpecifiedOnCommandLine private. Every value is still parsed by Abseil (CommandLineFlag::ParseFrom): typed, and a
// bad one is Abseil's error naming the flag and the value.
#pragma once

#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/flags/commandlineflag.h"
#include "absl/flags/flag.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace ss::cli {

struct Command {
  std::string name;   // as typed, e.g. "scenestreamer dataset sumo"; the words after the program prefix clashing flags
  std::string usage;  // synopsis and what the command does; --help prints it, then the flags
  std::string file;   // __FILE__ of the source file that defines the command's own flags
  std::vector<const absl::CommandLineFlag*> shared;  // the shared flags it takes
  bool positional = false;  // takes positional arguments (files); without, one is refused as unexpected
};

// A flag's handle, for Command::shared.
template <typename T>
const absl::CommandLineFlag* flag(const absl::Flag<T>& f) {
  return &absl::GetFlagReflectionHandle(f);
}

// What a command line held besides the flags' values (absl::GetFlag reads those).
class CommandLine {
 public:
  const std::vector<std::string>& positional() const { return positional_; }
  // Whether the flag was given, for rules like "--baseline runs without a model".
  template <typename T>
  bool has(const absl::Flag<T>& f) const {
    return given_.contains(flag(f));
  }
  // The first of `flags` that was given, as typed ("--top-p"); "" when none was.
  std::string first_given(std::initializer_list<const absl::CommandLineFlag*> flags) const;

 private:
  friend std::optional<int> parse_command(const Command&, int, char**, CommandLine*);
  std::vector<std::string> positional_;
  absl::flat_hash_map<const absl::CommandLineFlag*, std::string> given_;  // as typed
};

// Parses argv[1..argc) (argv[0] is the command's name): --flag value, --flag=value, --switch (a bool flag; or
// --switch=false), positional arguments anywhere, everything after "--" positional. Returns nullopt when the command
// is to run; otherwise its exit code: 0 after --help has printed the usage and the command's flags (help, default) to
// stdout, 2 after an unknown flag, a missing value or a bad one was reported on stderr.
std::optional<int> parse_command(const Command& command, int argc, char** argv, CommandLine* line);

// "<command name>: <message>" and where the usage is, on stderr; returns 2, the exit code of usage errors.
int usage_error(const Command& command, absl::string_view message);

// `usage`, then every flag defined in `file` (__FILE__ of the source that defines them) with its default and help, in
// the layout of a command's --help, the names as Abseil spells them (--snapshot_dir): for a program that parses its
// flags with absl::ParseCommandLine, like the server, whose --help Abseil would answer with the flags of a file
// named after the program only.
std::string file_flags_help(absl::string_view usage, absl::string_view file);

// Where the programs' bundled files are: the folder holding models/ (the default model and its card) and data/ (the
// sample scenarios). For an installed program (`cmake --install build --prefix P`), P/share/scenestreamer, found from
// the executable's own path (/proc/self/exe: <exe dir>/../share/scenestreamer); for a program run from the build tree
// it was built in, the source tree it was built from. Never the working directory. NOT_FOUND, naming the places
// looked at, when neither applies (a binary copied elsewhere without its share/ folder).
absl::StatusOr<std::string> bundled_dir();

}  // namespace ss::cli
