// Command-line arguments of one subcommand: --name value, --name=value, --switch, and positional arguments.
// Each subcommand declares its flags, so a misspelt flag is an error rather than silently ignored.
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace ss::cli {

struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> values;  // --name value
  std::set<std::string> switches;             // --name

  bool has(const std::string& name) const { return values.count(name) || switches.count(name); }
  std::string get(const std::string& name, const std::string& fallback = "") const;
};

// Parses argv[first..argc). `value_flags` take a value; `switch_flags` do not. Names are given without "--".
absl::StatusOr<Args> parse_args(int argc, char** argv, int first, const std::set<std::string>& value_flags,
                                const std::set<std::string>& switch_flags);

// The trained default model, where `make serve` and the server look for it (relative to the working directory).
inline constexpr const char* kDefaultModel = "models/default.safetensors";
// --model, or the default model when the flag is absent; NOT_FOUND saying so when neither exists.
absl::StatusOr<std::string> model_path(const Args& args);

}  // namespace ss::cli
