// `scenestreamer eval --compare A.json B.json`: two `eval --json` results of the same scenarios, each metric's
// difference B - A with a paired bootstrap interval over scenarios (offline/eval/compare.h).
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "offline/eval/compare.h"
#include "nlohmann/json.hpp"

namespace ss::cli {

struct CompareRequest {
  std::string a_path, b_path;
  BootstrapOptions bootstrap;
};

struct CompareReport {
  std::string table;   // for people
  nlohmann::json json;  // keys: a, b, scenarios, resamples, seed, level, metrics [{name, scenarios, a, b, difference,
                        // low, high, excludes_zero}]; undefined values are written as null by json_text()
};

// Reads both files, pairs their per_scenario entries by id and compares. Errors name the file and what is wrong:
// unreadable or not an eval result, scenarios that do not pair, different --sdc rules or evaluated objects.
absl::StatusOr<CompareReport> compare_eval_files(const CompareRequest& request);

}  // namespace ss::cli
