// `eval --protocol scenario-gen`: the Scenario Generation Challenge's run (offline/eval/scenario_gen.h): every
// scenario's scenes generated (or read from a submission), scored, written as JSON, a table and, on request, as a
// submission.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "offline/eval/scenario_gen.h"
#include "offline/eval/submission.h"

namespace ss::cli {

struct ScenarioGenRun {
  std::vector<std::shared_ptr<const Scenario>> scenarios;
  ScenarioGenOptions options;
  std::shared_ptr<const Model> model;  // the model policy only
  std::string model_path;
  int threads = 1;
  std::string json_out;         // '-' for stdout
  std::string submission_in;    // the submission policy: the files read
  std::string submission_out;   // write the scenes as a submission here (empty: none)
  SubmissionMetadata metadata;
};

// Returns the exit code; errors are logged.
int run_scenario_gen(ScenarioGenRun& run);

}  // namespace ss::cli
