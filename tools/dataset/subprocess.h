// Running the SUMO programs: posix_spawn with an argument vector (no shell, so no quoting), the child's stdout and
// stderr written to files (no pipe to deadlock on), a working directory, and extra environment variables.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace ss::dataset {

struct Command {
  std::string program;             // absolute path (see find_program)
  std::vector<std::string> args;   // argv[1..]
  std::string cwd;                 // empty: the caller's
  std::vector<std::string> env;    // "NAME=value" added to (or replacing in) the caller's environment
  std::string stdout_path = "/dev/null";
  std::string stderr_path;         // required: what the program said is kept for error messages
};

struct CommandResult {
  int exit_code = 0;    // when the program exited
  int signal = 0;       // when a signal ended it (SUMO's assertions abort: SIGABRT)
  std::string stderr_text;
  double seconds = 0;

  bool ok() const { return signal == 0 && exit_code == 0; }
  // "exit code 1" / "killed by signal 6 (Aborted)", then the last lines of stderr.
  std::string describe() const;
};

// Runs the command to completion. Errors only when it cannot be started (the program is missing or not executable).
absl::StatusOr<CommandResult> run_command(const Command& c);

// The absolute path of `name`: as given when it contains a '/', else the first executable match in `search_path`
// (a PATH-style list). NOT_FOUND names the program and where it looked.
absl::StatusOr<std::string> find_program(const std::string& name, const std::string& search_path);

// The last `max_lines` lines of `text`, for error messages.
std::string tail_lines(const std::string& text, int max_lines);

}  // namespace ss::dataset
