// One generation job's working directory and the steps it runs: every error names the job (index, seed, network)
// and the step that failed, with what the program printed.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "tools/dataset/sumo_tools.h"

namespace ss::dataset {

// A fresh directory under `root`, removed with everything in it when this object goes (unless kept).
class TempDir {
 public:
  static absl::StatusOr<TempDir> create(const std::string& root, const std::string& prefix);
  TempDir(TempDir&& o) noexcept : path_(std::move(o.path_)), keep_(o.keep_) { o.path_.clear(); }
  TempDir& operator=(TempDir&&) = delete;
  ~TempDir();
  const std::string& path() const { return path_; }
  void keep() { keep_ = true; }

 private:
  explicit TempDir(std::string path) : path_(std::move(path)) {}
  std::string path_;
  bool keep_ = false;
};

class JobContext {
 public:
  JobContext(const SumoTools& tools, std::string dir, std::string label)
      : tools_(tools), dir_(std::move(dir)), label_(std::move(label)) {}

  const SumoTools& tools() const { return tools_; }
  const std::string& label() const { return label_; }
  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  // Runs `program args` in the job directory with SUMO_HOME set; stderr goes to <step>.stderr (stdout to
  // <stdout_name> when given). A non-zero exit or a signal is an ABORTED error naming the step: the program ran and
  // failed on this job's inputs (another draw of them may work); a program that cannot start is INTERNAL.
  absl::Status run(const std::string& step, const std::string& program, const std::vector<std::string>& args,
                   const std::string& stdout_name = "");
  // What the last run of `step` wrote to stderr.
  std::string stderr_of(const std::string& step) const;

  absl::StatusOr<std::string> read(const std::string& step, const std::string& name) const;
  absl::Status write(const std::string& step, const std::string& name, const std::string& content) const;
  // An error at `step`: "<label>: step <step>: <what>" (INTERNAL, or ABORTED when `inputs_failed`: this job's
  // random inputs did not work out).
  absl::Status error(const std::string& step, const std::string& what, bool inputs_failed = false) const;

  void add_time(const std::string& step, double seconds) { seconds_[step] += seconds; }
  const std::map<std::string, double>& seconds() const { return seconds_; }

 private:
  const SumoTools& tools_;
  std::string dir_, label_;
  std::map<std::string, double> seconds_;
  std::map<std::string, std::string> stderr_;
};

}  // namespace ss::dataset
