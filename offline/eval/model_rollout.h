// The model as a policy for the metrics: a session rolled out to the scenario's last frame, and its 2 Hz steps as a
// 10 Hz joint scene aligned with the log's sim agents.
#pragma once

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "offline/eval/joint_scene.h"
#include "offline/eval/mmd.h"
#include "engine/sim/session.h"

namespace ss {

// The scenario up to its current frame: tracks, timestamps and light states after it dropped, the map kept. What a
// session is created with, so that no logged future pose can reach it except through the controls.
Scenario history_only(const Scenario& s);

// What reached a rollout's session (tests check that no logged future pose did under SdcRule::model).
struct RolloutInputs {
  std::shared_ptr<const Scenario> scenario;         // the scenario the session was created with
  SessionOptions options;
  std::vector<std::vector<ControlInput>> controls;  // per step
};

// Runs a session from the scenario's current step for `steps` 2 Hz steps; -1: until the scenario's last frame is
// covered. The session is given history_only(scenario). SdcRule::model: the session controls no agent and the model
// drives the SDC like every other agent (`options.control_sdc` and `controlled_ids` are overridden). SdcRule::log:
// the SDC is the controlled agent and replays its logged pose at every step while the log has one (then keeps its
// last control). Returns the steps from the current one on (the first is Session::current() after creation).
absl::StatusOr<std::vector<StepResult>> run_model_rollout(std::shared_ptr<const Model> model,
                                                          std::shared_ptr<const Scenario> scenario,
                                                          std::shared_ptr<const MapContext> map,
                                                          const SessionOptions& options, SdcRule sdc, int steps = -1,
                                                          RolloutInputs* inputs = nullptr);

struct RolloutScene {
  // Objects [0, tracks.size()) are the given tracks in order (the log's sim agents); after them, the agents the
  // model created that stand in for no track (obstacles only).
  JointScene scene;
  int driven_frames = 0;  // (track, frame) after the current frame that the model moved
  int filled_frames = 0;  // ... that moved at constant velocity because the model did not drive the track there
  int to_match = 0, matched = 0;  // full mode: tracks to stand in for, and how many got a generated agent
  double match_distance = 0;      // mean distance between paired track and generated agent at the current frame
};

// Frames up to the current one are the log's; after it, each track follows its agent's upsampled (10 Hz) states.
// A track the model does not drive (outside the session's region, of a type it does not model, or after it
// retires) moves on at constant velocity from its last state, so every sim agent has a full trajectory as WOSAC
// requires. Box size and height are held from the current frame, the height (z) too: the model works in the plane.
// `match_generated` (full mode, where the model creates the agents at the current step): each track except those
// in the session under their own id (the SDC) is paired with a generated agent of the same type, nearest pairs
// first; a paired track takes the agent's trajectory and size, and its logged history is moved rigidly onto the
// agent's initial pose so the history joins the rollout smoothly.
RolloutScene rollout_scene(const Scenario& s, const std::vector<int>& tracks, const std::vector<StepResult>& steps,
                           bool match_generated);

// Initial states for the MMD: the session's agents at its first step that it did not take from the caller
// (controlled agents are the log's), and the log's vehicles, pedestrians and cyclists valid at the current frame
// except the SDC.
std::vector<InitialAgent> generated_initial_agents(const StepResult& first);
std::vector<InitialAgent> log_initial_agents(const Scenario& s);
// The frame the MMD attributes are measured in: the SDC's current pose, or the scenario's focus with heading 0
// when it names no SDC.
Pose mmd_frame(const Scenario& s);

}  // namespace ss
