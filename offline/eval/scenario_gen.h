// The Waymo Open Dataset 2025 Scenario Generation Challenge as `eval --protocol scenario-gen` scores it: given the
// map, the ego's (SDC's) one second of history and the number of agents of each type, 32 generated scenes of the
// whole scenario (every sim agent's box and its 91 frames: history, current frame and future), scored by the
// sim-agents features with the histograms pooled over every object (aggregate_objects) instead of per object, so a
// generated agent needs no partner in the log (waymo-open-dataset challenge_2025_scenario_gen_config.textproto,
// estimators.py, metric_features.py; docs/evaluation.md, "Scenario generation").
#pragma once

#include <array>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "offline/eval/meta_metric.h"
#include "offline/eval/mmd.h"
#include "offline/eval/placed_agents.h"
#include "offline/eval/scene_features.h"
#include "engine/sim/map_cache.h"
#include "engine/sim/session.h"

namespace ss {

// The agents the challenge asks for: per model type (vehicles, pedestrians, cyclists), the scenario's sim agents
// (every track valid at the current frame) but the SDC, whose state it gives. A sim agent of another type (WOMD's
// "other") has no count: scenario_gen_problem names it.
std::array<int, 3> scenario_gen_counts(const Scenario& s);
// Why the challenge's scene cannot be built for `s` (empty: it can): no agent valid now, a sim agent of a type the
// model does not generate, a current frame that is not the challenge's 2 Hz grid.
std::string scenario_gen_problem(const Scenario& s);
// "V,P,C" as three counts, each 0..1024.
absl::StatusOr<std::array<int, 3>> parse_agent_counts(const std::string& text);

// The config's aggregate_objects: every feature but the traffic-light violation (scored per object, as in
// sim agents). independent_timesteps holds for every histogram feature, as in sim agents.
bool scenario_gen_aggregated(RealismFeature f);

// The challenge's per-scenario scores. `log` and every `sims` entry hold the features of all frames (scene_features
// with current_frame -1) of the same objects (the sim agents), `log.valid` the log's validity (the scoring mask),
// `types` the log's types (time to collision and light violations mask vehicles). Aggregated histograms: one
// histogram of every rollout's, object's and frame's value (unmasked; NaN in the last bin), each masked log value
// scored under it, one joint mean. Aggregated Bernoulli: each (rollout, object)'s "any in the log-valid frames" in
// one sample, each log object's scored under it, the mean over objects. ADE and minADE are undefined (NaN): no
// generated agent stands for a logged one (the official code writes 0).
RealismScores score_scenario_gen(const SceneFeatures& log, std::span<const SceneFeatures> sims,
                                 std::span<const ObjectType> types);

// A generated scene and what the challenge checks of it.
struct GeneratedScene {
  JointScene scene;                   // objects: the sim agents (sim_agent_tracks order), every frame valid
  std::vector<InitialAgent> initial;  // initial_agents(scene): what the initial-state MMD compares
  std::array<int, 3> placed{};        // generated agents per model type
  int overlapping_pairs = 0;          // pairs of boxes overlapping at the current frame (the SDC's included)
  int filled = 0;                     // agents placed by the placement baseline's rule: the model had no slot
};

// The counts asked of the model: `requested` cut to `slots` agents (its largest type first), for a scenario with
// more sim agents than the model has agent slots (one val scenario: 130 against 128).
std::array<int, 3> model_request(std::array<int, 3> requested, int slots);

// How a generated agent's history (the frames before the current one, which the model does not generate: docs/model.md,
// "Scenario generation") is made. constant_velocity: it moves back along its generated velocity, heading held.
// clear: the same, but where that step back would overlap another box at that frame (the SDC's logged one, or another
// generated agent's) it holds the pose of the frame after from there back (clear_history).
enum class ScenarioGenHistory { constant_velocity, clear };
// The history frames (now - 1 down to 0) of the objects `moved` made clear of every other box: going back in time
// each steps back along its own history unless that box would overlap another box of that frame (the objects not in
// `moved` keep theirs; the others' steps back and holds are decided together, until none changes, so the order of
// `moved` does not matter); then it holds the pose of the frame after from there back: it was standing there and
// moved off later. Where holding overlaps a box not in `moved` too (it moves into this place), the step back is
// kept.
void clear_history(JointScene& scene, int now, const std::vector<size_t>& moved);
const char* scenario_gen_history_name(ScenarioGenHistory h);

// A full-mode rollout (run_model_rollout with options.agent_counts = `requested`, SdcRule::model) as the
// challenge's scene: the SDC keeps its logged history up to the current frame, then the model's; the generated
// agents of each type wear the ids of the log's sim agents of that type in track order (blind to where the log's
// are: the id only decides which log object's validity masks its indications, as in the official scorer). Before
// the current frame a generated agent moves back along its generated velocity at constant speed and heading (the
// model places the scene at the current frame: docs/model.md, "Scenario generation"); its z is the ground's under
// it plus half its height. An error when the rollout's counts are not `requested`. Sim agents beyond `requested`
// (model_request cut it) are placed by the placement baseline's rule (within `radius`, drawn from `seed`) and counted
// in `filled`.
absl::StatusOr<GeneratedScene> generated_scene(const Scenario& s, const std::vector<StepResult>& steps,
                                               const std::array<int, 3>& requested, double radius, uint64_t seed,
                                               ScenarioGenHistory history = ScenarioGenHistory::constant_velocity);

// The placement baseline: the requested counts placed at random points within `radius` of the SDC (vehicles and
// cyclists on lane centres along the lane, pedestrians beside the road edges on their off-road side, 1.5 m out, or
// on crosswalk corners), each with the box and speed of a random log agent of its type at the current frame
// (redrawn up to 50 times where it would overlap a box already placed), moving at constant velocity through every
// frame; the SDC keeps its history and moves on at constant velocity.
GeneratedScene placement_scene(const Scenario& s, double radius, uint64_t seed);

// The log oracle: every sim agent's logged states, each invalid frame filled at constant velocity from the nearest
// valid one (a submission has a state at every frame).
GeneratedScene log_oracle_scene(const Scenario& s);

// The initial states of a scene's agents but the SDC, as its frames show them: the box at the current frame, the
// velocity from the frame before it to the current one (for a generated agent, whose history moves back at its
// generated velocity, that velocity; read the same from a submission file).
std::vector<InitialAgent> initial_agents(const Scenario& s, const JointScene& scene);

// The log as the scorer reads it: the sim agents' logged boxes at every frame, with the log's validity.
JointScene scenario_gen_log_scene(const Scenario& s);

// x, y, z, heading and the box rounded to float32 at every frame: what a submission file holds.
void round_scene_to_submission(JointScene& scene);

enum class ScenarioGenPolicy { model, log_oracle, placement, submission };
const char* scenario_gen_policy_name(ScenarioGenPolicy p);

struct ScenarioGenOptions {
  ScenarioGenPolicy policy = ScenarioGenPolicy::model;
  SessionOptions session;  // model: full mode; agent_counts is set per scenario; seed is the base seed
  int rollouts = 32;
  double placement_radius = 100.0;  // the placement baseline's region around the SDC (the session's roi_radius)
  bool submission_precision = false;  // score the scenes as a submission file holds them (float32)
  ScenarioGenHistory history = ScenarioGenHistory::constant_velocity;  // the model's generated agents
};

struct ScenarioGenEvaluation {
  std::string id;
  int sim_agents = 0;
  int rollouts = 0;
  std::array<int, 3> requested{};
  RealismScores realism;
  InitialStateMmd mmd_strict, mmd_relaxed;  // means over rollouts (NaN where a set was empty in every rollout)
  // One MMD of every rollout's agents pooled against the log's: the scenario's generated distribution, not one draw of
  // it (a per-rollout MMD of 10-30 agents is far from 0 for two samples of one distribution already).
  InitialStateMmd mmd_pooled_strict, mmd_pooled_relaxed;
  int exact_rollouts = 0;                   // rollouts whose counts per type are the requested ones
  int filled = 0;                           // agents placed by rule for want of a model slot, over the rollouts
  int overlapping_rollouts = 0;             // rollouts with a pair of boxes overlapping at the current frame
  PlacedAgents placed_log, placed_generated;  // the log's agents but the SDC; the generated, summed over rollouts
};

// `submitted`: the scenario's scenes read from a submission (scenegen_scenes_from_rollouts), for that policy only.
// `scenes` (optional) receives the scored scenes.
absl::StatusOr<ScenarioGenEvaluation> evaluate_scenario_gen(std::shared_ptr<const Scenario> scenario,
                                                            const ScenarioGenOptions& options,
                                                            std::shared_ptr<const Model> model, MapCache* maps,
                                                            const std::vector<JointScene>* submitted = nullptr,
                                                            std::vector<JointScene>* scenes = nullptr);

// Means over scenarios (values undefined in a scenario are left out of their mean), placement counts summed.
struct ScenarioGenDataset {
  int scenarios = 0, rollouts = 0;
  RealismScores realism;
  InitialStateMmd mmd_strict, mmd_relaxed, mmd_pooled_strict, mmd_pooled_relaxed;
  int exact_rollouts = 0, overlapping_rollouts = 0, total_rollouts = 0, filled = 0;
  PlacedAgents placed_log, placed_generated;
};
ScenarioGenDataset aggregate_scenario_gen(std::span<const ScenarioGenEvaluation> scenarios);

}  // namespace ss
