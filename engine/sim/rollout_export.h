// A rollout as a complete WOMD Scenario: the log up to its current frame, the session's 2 Hz steps upsampled to
// 10 Hz after it, so every WOMD tool (WOSAC scorers, other simulators, `render`) reads it as an ordinary scenario.
#pragma once

#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/session.h"

namespace ss {

// One agent of a rollout at 10 Hz: frame j is j / 10 s after the first step (j = 5 k is step k). Invalid where the
// agent was not in the session (before it entered, after it retired).
struct RolloutAgent {
  int64_t id = 0;   // the session's public id: the track id for log agents
  int type = 0;     // model type: 0 vehicle, 1 pedestrian, 2 cyclist
  std::vector<StepState> frames;
};

// Every agent ever present in `steps` (consecutive results of one session), in order of first appearance, upsampled
// with upsample_states. The one conversion of a session's steps to 10 Hz: the export and the metrics both use it.
std::vector<RolloutAgent> rollout_agents(const std::vector<StepResult>& steps);

// `steps` start at the session's first step, which is the source's current frame (Session::current() after
// creation). The output:
// - keeps the source's id, map, sensor data, current_time_index, sdc_track_index, tracks_to_predict and
//   objects_of_interest, and every frame up to the current one as logged (tracks, timestamps, signal states);
// - after the current frame, (steps - 1) * 5 frames at 10 Hz, timestamps continuing the log's current one by 0.1 s;
//   each log track follows its session agent (invalid where the session did not have it); z is held from the track's
//   last logged z, since the model works in the plane;
// - the agents the model created as new tracks after the log's (their ids count up from above the log's largest,
//   so they cannot collide), valid while present, z from the nearest lane point;
// - signal states after the current frame: the model's light states, held between steps, with the stop point's z
//   from the log's latest stop point of that lane (else the nearest lane point).
// INVALID_ARGUMENT when `steps` is empty or does not start at the source's current frame, or an id exceeds int32.
absl::StatusOr<Scenario> rollout_to_scenario(const Scenario& source, const std::vector<StepResult>& steps);

}  // namespace ss
