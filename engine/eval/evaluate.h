// One scenario's evaluation: K rollouts of a policy (the model in a session mode, constant velocity, or log replay)
// scored with the WOSAC realism metrics, the motion metrics and, for generated scenes, the initial-state MMD.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/eval/meta_metric.h"
#include "engine/eval/mmd.h"
#include "engine/eval/motion_metrics.h"
#include "engine/sim/map_cache.h"
#include "engine/sim/session.h"

namespace ss {

enum class EvalPolicy { model, constant_velocity, log_replay };
const char* eval_policy_name(EvalPolicy p);

struct EvalOptions {
  EvalPolicy policy = EvalPolicy::model;
  SessionOptions session;  // the model's mode and sampling; session.seed is the base seed of every rollout
  int rollouts = 4;        // K
};

// Counts of sim and log feature values over kPlotBins equal bins of the feature's WOSAC range (values clipped),
// over the frames the feature scores: what `eval --plots` draws.
inline constexpr int kPlotBins = 40;
struct FeatureHistogram {
  std::vector<double> log, sim;
};

struct ScenarioEvaluation {
  std::string id;
  bool named_by_scenario = false;  // evaluated objects: SDC + tracks_to_predict (else every agent valid now)
  int evaluated = 0;               // evaluated objects
  int sim_agents = 0;              // agents valid at the current frame
  RealismScores realism;
  MotionMetrics motion_all;        // every sim agent but the SDC (which replays its log in the model's rollouts)
  MotionMetrics motion_predict;    // tracks_to_predict (the evaluated objects when the scenario names none), no SDC
  bool has_mmd = false;            // full mode: the model generated the initial state
  InitialStateMmd mmd_strict, mmd_relaxed;  // means over rollouts (NaN when a set was empty in every rollout)
  double filled_share = 0;         // model: share of sim-agent frames after now moved at constant velocity instead
  int to_match = 0, matched = 0;   // full mode, summed over rollouts: tracks to stand in for, and paired
  double match_distance = 0;       // full mode: mean distance of the pairs at the current frame
  std::array<FeatureHistogram, kNumRealismFeatures> histograms;  // continuous features only
};

// The seed of one rollout: depends on the base seed, the scenario's id and the rollout's index only, so results do
// not depend on the order or the thread scenarios are evaluated in.
uint64_t rollout_seed(uint64_t base, const std::string& scenario_id, int rollout);

// `model` and `maps` are needed (non-null) for EvalPolicy::model only.
absl::StatusOr<ScenarioEvaluation> evaluate_scenario(std::shared_ptr<const Scenario> scenario, const EvalOptions& options,
                                                     std::shared_ptr<const Model> model, MapCache* maps);

}  // namespace ss
