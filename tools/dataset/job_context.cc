#include "tools/dataset/job_context.h"

#include <stdlib.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "tools/dataset/subprocess.h"

namespace ss::dataset {

absl::StatusOr<TempDir> TempDir::create(const std::string& root, const std::string& prefix) {
  std::string templ = root + "/" + prefix + "XXXXXX";
  if (::mkdtemp(templ.data()) == nullptr)
    return absl::FailedPreconditionError(
        absl::StrCat("cannot create a temporary directory in ", root, ": ", std::strerror(errno)));
  return TempDir(templ);
}

TempDir::~TempDir() {
  if (path_.empty() || keep_) return;
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

absl::Status JobContext::error(const std::string& step, const std::string& what, bool inputs_failed) const {
  const std::string message = absl::StrCat(label_, ": step ", step, ": ", what);
  return inputs_failed ? absl::AbortedError(message) : absl::InternalError(message);
}

absl::Status JobContext::run(const std::string& step, const std::string& program, const std::vector<std::string>& args,
                             const std::string& stdout_name) {
  Command c;
  c.program = program;
  c.args = args;
  c.cwd = dir_;
  c.env = tools_.env();
  c.stderr_path = path(step + ".stderr");
  if (!stdout_name.empty()) c.stdout_path = path(stdout_name);
  auto r = run_command(c);
  if (!r.ok()) return error(step, std::string(r.status().message()));
  add_time(step, r->seconds);
  stderr_[step] = r->stderr_text;
  if (!r->ok())
    return error(step, absl::StrCat(std::filesystem::path(program).filename().string(), " failed: ", r->describe()),
                 /*inputs_failed=*/true);
  return absl::OkStatus();
}

std::string JobContext::stderr_of(const std::string& step) const {
  auto it = stderr_.find(step);
  return it == stderr_.end() ? "" : it->second;
}

absl::StatusOr<std::string> JobContext::read(const std::string& step, const std::string& name) const {
  std::ifstream in(path(name), std::ios::binary);
  if (!in) return error(step, absl::StrCat("cannot read ", name, " (the step wrote no such file)"));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

absl::Status JobContext::write(const std::string& step, const std::string& name, const std::string& content) const {
  std::ofstream out(path(name), std::ios::binary);
  out << content;
  out.close();
  if (!out) return error(step, absl::StrCat("cannot write ", path(name)));
  return absl::OkStatus();
}

}  // namespace ss::dataset
