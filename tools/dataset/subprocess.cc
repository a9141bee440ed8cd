#include "tools/dataset/subprocess.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"

extern char** environ;

namespace ss::dataset {
namespace {

bool is_executable_file(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
}

std::string read_file_or_empty(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The caller's environment with `extra` ("NAME=value") added, replacing variables of the same name.
std::vector<std::string> merged_environment(const std::vector<std::string>& extra) {
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    const std::string var = *e;
    const std::string name = var.substr(0, var.find('='));
    bool replaced = false;
    for (const std::string& x : extra) replaced = replaced || x.substr(0, x.find('=')) == name;
    if (!replaced) env.push_back(var);
  }
  env.insert(env.end(), extra.begin(), extra.end());
  return env;
}

class FileActions {
 public:
  FileActions() { posix_spawn_file_actions_init(&fa_); }
  ~FileActions() { posix_spawn_file_actions_destroy(&fa_); }
  posix_spawn_file_actions_t* get() { return &fa_; }

 private:
  posix_spawn_file_actions_t fa_;
};

}  // namespace

std::string CommandResult::describe() const {
  std::string what = signal ? absl::StrCat("killed by signal ", signal, " (", strsignal(signal), ")")
                            : absl::StrCat("exit code ", exit_code);
  const std::string tail = tail_lines(stderr_text, 6);
  return tail.empty() ? what : absl::StrCat(what, "; stderr:\n", tail);
}

std::string tail_lines(const std::string& text, int max_lines) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.find_first_not_of(" \t\r") != std::string::npos) lines.push_back(line);
  std::string out;
  for (size_t i = lines.size() > static_cast<size_t>(max_lines) ? lines.size() - max_lines : 0; i < lines.size(); ++i)
    absl::StrAppend(&out, out.empty() ? "" : "\n", lines[i]);
  return out;
}

absl::StatusOr<std::string> find_program(const std::string& name, const std::string& search_path) {
  if (name.find('/') != std::string::npos) {
    if (is_executable_file(name)) return name;
    return absl::NotFoundError(absl::StrCat(name, ": no such executable file"));
  }
  size_t start = 0;
  while (start <= search_path.size()) {
    size_t end = search_path.find(':', start);
    if (end == std::string::npos) end = search_path.size();
    std::string dir = search_path.substr(start, end - start);
    if (dir.empty()) dir = ".";
    const std::string candidate = dir + "/" + name;
    if (is_executable_file(candidate)) return candidate;
    start = end + 1;
  }
  return absl::NotFoundError(absl::StrCat(name, " not found in PATH (", search_path, ")"));
}

absl::StatusOr<CommandResult> run_command(const Command& c) {
  FileActions fa;
  posix_spawn_file_actions_addopen(fa.get(), STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(fa.get(), STDOUT_FILENO, c.stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(fa.get(), STDERR_FILENO, c.stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (!c.cwd.empty()) posix_spawn_file_actions_addchdir_np(fa.get(), c.cwd.c_str());

  std::vector<std::string> env = merged_environment(c.env);
  std::vector<char*> argv, envp;
  argv.push_back(const_cast<char*>(c.program.c_str()));
  for (const std::string& a : c.args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  for (const std::string& e : env) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);

  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int err = posix_spawn(&pid, c.program.c_str(), fa.get(), nullptr, argv.data(), envp.data());
  if (err != 0) return absl::FailedPreconditionError(absl::StrCat("cannot start ", c.program, ": ", std::strerror(err)));
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return absl::InternalError(absl::StrCat("waitpid for ", c.program, ": ", std::strerror(errno)));
  }
  CommandResult r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  else if (WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
  r.stderr_text = read_file_or_empty(c.stderr_path);
  // glibc's posix_spawn reports a failed exec in the child (a bad working directory, say) as exit code 127.
  if (r.exit_code == 127 && r.stderr_text.empty())
    return absl::FailedPreconditionError(absl::StrCat("cannot start ", c.program, " (exit code 127: exec or chdir failed)"));
  return r;
}

}  // namespace ss::dataset
