// What `scenestreamer eval` writes: one JSON object and a readable table.
#pragma once

#include <optional>
#include <span>
#include <string>

#include "offline/eval/aggregate.h"
#include "offline/eval/evaluate.h"
#include "nlohmann/json.hpp"

namespace ss::cli {

struct EvalRunInfo {
  EvalPolicy policy = EvalPolicy::model;
  SdcRule sdc = SdcRule::model;
  SessionMode mode = SessionMode::motion;
  int rollouts = 0;
  uint64_t seed = 0;
  double top_p = 0, temperature = 0;  // the model's sampling
  bool motion_reject = true;           // reject sampling of motion (SessionOptions::motion_reject)
  std::optional<EgoPolicy> ego;        // the closed-loop ego benchmark's policy
  int no_ego = 0;                      // --ego: scenarios left out for naming no SDC
  std::string model_path;  // empty for the baselines
};

// Keys: scenarios, rollouts, policy, sdc, realism_meta, <feature>_likelihood, kinematic, interactive, map,
// collision_rate, offroad_rate, min_ade, ade_avg, ade_min, fde_avg, fde_min, add, fdd (all agents),
// tracks_to_predict {...}, windows [...] (realism per window), mmd {strict, relaxed} in full mode, evaluated_objects,
// ego {...} under --ego (episode shares: collision, rear_end, ego_at_fault, side, background_fault, off_road, and
// background_collision_rate), per_scenario [...] (the same per scenario, with its windows, evaluated ids and the model's driven share).
// Undefined values (NaN) are written as null by json_text() (engine/io/json_text.h).
nlohmann::json eval_json(const EvalRunInfo& run, const DatasetEvaluation& d, std::span<const ScenarioEvaluation> scenarios);

std::string eval_table(const EvalRunInfo& run, const DatasetEvaluation& d);

}  // namespace ss::cli
