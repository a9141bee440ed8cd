// One scenario's evaluation: K rollouts of a policy (the model in a session mode, constant velocity, or log replay)
// scored with the WOSAC realism metrics, the motion metrics and, for generated scenes, the initial-state MMD.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "offline/eval/ego_loop.h"
#include "offline/eval/meta_metric.h"
#include "offline/eval/mmd.h"
#include "offline/eval/motion_metrics.h"
#include "offline/eval/placed_agents.h"
#include "engine/sim/map_cache.h"
#include "engine/sim/session.h"

namespace ss {

// submission: rollouts made elsewhere (a WOSAC submission, read with submission.h), scored as given.
enum class EvalPolicy { model, constant_velocity, log_replay, submission };
const char* eval_policy_name(EvalPolicy p);

struct EvalOptions {
  EvalPolicy policy = EvalPolicy::model;
  SdcRule sdc = SdcRule::model;  // who drives the SDC (joint_scene.h); under log it is not evaluated
  SessionOptions session;  // the model's mode and sampling; session.seed is the base seed of every rollout
  int rollouts = 4;        // K (a submission brings its own)
  // Score each rollout's future as a submission holds it (x, y, z, heading rounded to float32: round_to_submission),
  // so that scoring the submission written from these rollouts gives the same numbers.
  bool submission_precision = false;
  // The closed-loop ego benchmark (ego_loop.h): the SDC driven by this policy through the session's tick, the way a
  // client drives it (needs the model policy and SdcRule::log; the session modes log and idm are its baselines).
  std::optional<EgoPolicy> ego;
};

// The ego benchmark's counts over one scenario's rollouts (episodes).
struct EgoSummary {
  int episodes = 0;
  int collided = 0;                        // episodes with an ego collision
  int rear_end = 0, ego_at_fault = 0, side = 0;  // ... by the first collision's kind (ego_loop.h)
  int off_road = 0;                        // episodes in which the ego left the road
  double background_collision_rate = 0;    // mean over episodes of the share of background agents that collided
                                           // with another background agent
  std::vector<EgoOutcome> outcomes;        // each episode's, in rollout order
};

// Realism per window of the simulated future, so the drift of a long rollout shows: 0-8 s, 8-16 s, 16 s to the end
// (frames counted after the current one; a 91-frame WOMD scenario has only the first, equal to the whole).
inline constexpr int kRealismWindowFrames = 80;  // 8 s at 10 Hz
inline constexpr int kNumRealismWindows = 3;
// The windows a future of `future_frames` frames has (those with at least one frame), in order.
std::vector<FrameWindow> realism_windows(int future_frames);
const char* realism_window_name(int window);  // "0-8 s", "8-16 s", "16 s-end"

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
  SdcRule sdc = SdcRule::model;
  int64_t sdc_id = -1;             // the SDC's object id; -1 when the scenario names none
  std::vector<int64_t> evaluated_ids;  // the evaluated objects' ids, in WOSAC's order
  int future_frames = 0;           // frames after the current one (80 in a 91-frame WOMD scenario)
  int rollouts = 0;                // rollouts scored
  RealismScores realism;           // over the whole future
  std::vector<RealismScores> windows;  // per realism_windows(future_frames)
  MotionMetrics motion_all;        // every sim agent (but the SDC under SdcRule::log)
  MotionMetrics motion_predict;    // tracks_to_predict (the evaluated objects when the scenario names none), the
                                   // SDC left out under SdcRule::log
  bool has_mmd = false;            // full mode: the model generated the initial state
  InitialStateMmd mmd_strict, mmd_relaxed;  // means over rollouts (NaN when a set was empty in every rollout)
  double filled_share = 0;         // model: share of sim-agent frames after now moved at constant velocity instead
                                   // (the rest, 1 - filled_share, is the share the model drove)
  int to_match = 0, matched = 0;   // full mode, summed over rollouts: tracks to stand in for, and paired
  double match_distance = 0;       // full mode: mean distance of the pairs at the current frame
  // Full mode: the log's agents in the session's region at the current frame, and the agents the model placed at
  // its first step, summed over the rollouts.
  PlacedAgents placed_log, placed_generated;
  std::array<FeatureHistogram, kNumRealismFeatures> histograms;  // continuous features only
  bool has_ego = false;            // EvalOptions::ego was set
  EgoSummary ego;
};

// The seed of one rollout: depends on the base seed, the scenario's id and the rollout's index only, so results do
// not depend on the order or the thread scenarios are evaluated in.
uint64_t rollout_seed(uint64_t base, const std::string& scenario_id, int rollout);

// `model` and `maps` are needed (non-null) for EvalPolicy::model only; `submitted` for EvalPolicy::submission only
// (the scenario's rollouts as scenes_from_rollouts builds them). `scenes` (optional) receives the scored rollouts:
// objects [0, sim agents) are the sim agents in track order, as rollouts_from_scenes expects.
absl::StatusOr<ScenarioEvaluation> evaluate_scenario(std::shared_ptr<const Scenario> scenario, const EvalOptions& options,
                                                     std::shared_ptr<const Model> model, MapCache* maps,
                                                     const std::vector<JointScene>* submitted = nullptr,
                                                     std::vector<JointScene>* scenes = nullptr);

}  // namespace ss
