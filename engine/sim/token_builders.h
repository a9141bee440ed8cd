// The decoder tokens of one step, built from agents' and lights' states: the one token layout of the project.
// Sessions build their steps with these, and the trainer's teacher-forced sequences (teacher_forcing.h) too.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/model/token.h"
#include "engine/scenario/scenario.h"
#include "engine/tokens/agent_state.h"
#include "engine/tokens/light.h"
#include "engine/tokens/resample.h"

namespace ss {

// An agent as its tokens see it.
struct TokenAgent {
  int64_t id = 0;       // its object in the sequence
  int slot = 0;         // agent-id embedding slot
  int type = 0;         // 0 vehicle, 1 pedestrian, 2 cyclist
  StepState state;
  int last_motion = 0;  // the motion token that brought it to this step (START when it appears)
};

// A traffic light: the lane it controls and its place on the map.
struct TokenLight {
  int64_t lane = 0;
  int map_id = 0;  // the segment of its lane nearest its stop point
  Pose pose;       // stop point, heading of that segment
};

// The anchor segment of a state: the nearest segment heading within 90 degrees of it, or any nearest segment.
int anchor_segment(const SegmentIndex& index, const StepState& s);
// The RS token's input: each field's bin scaled to [-1, 1].
std::array<float, kRsFields> scaled_relative_state(const StateBins& bins);
// The relative-state bins of `s` against segment `anchor`.
StateBins relative_state_bins(const StepState& s, const Pose& anchor);

// The light token of light `index` (its slot) at `step`.
DecoderToken light_token(int step, int index, const TokenLight& light, LightState state);
// SOA, TYPE, MS (anchor segment `seg`), RS of an agent at `order` in the step's group, from its state.
void agent_group_tokens(int step, const TokenAgent& a, int order, int seg, const MapSegment& anchor,
                        std::vector<DecoderToken>& out);
DecoderToken agent_motion_token(int step, const TokenAgent& a);
DecoderToken sos_token(int step);
DecoderToken eos_token(int step);

// The lights of a scenario: the lanes with a signal state at `frame`, by lane id, at most `max_lights`, each anchored
// on its lane's segment nearest its stop point (any nearest segment when the lane has none).
std::vector<TokenLight> scenario_lights(const Scenario& s, int frame, std::span<const MapSegment> segments,
                                        const SegmentIndex& index, int max_lights);
// The log's state of `lane`'s light at `frame` (unknown when the log has none).
LightState log_light_state(const Scenario& s, int64_t lane, int frame);

}  // namespace ss
