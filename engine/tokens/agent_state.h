// Agent-state tokens: an anchor map segment (the MS token) and the agent's state relative to it, 8 fields of 81
// uniform bins (the RS token; paper appendix D and E).
#pragma once

#include <array>
#include <span>

#include "absl/status/statusor.h"
#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/tokens/resample.h"

namespace ss {

inline constexpr int kStateBins = 81;
inline constexpr int kStateFields = 8;

// Field order of the relative state (the order the relative-state head generates them in).
enum StateField : int { kFieldLength = 0, kFieldWidth, kFieldHeight, kFieldU, kFieldV, kFieldHeading, kFieldVx, kFieldVy };

struct FieldRange {
  double min, max;
};
// Paper appendix E: l [0.5, 10], w [0.5, 3], h [0.5, 4], u, v [-10, 10], dpsi [-pi/2, pi/2], vx [0, 30], vy [-10, 10].
inline constexpr std::array<FieldRange, kStateFields> kStateRanges = {{
    {0.5, 10}, {0.5, 3}, {0.5, 4}, {-10, 10}, {-10, 10}, {-kPi / 2, kPi / 2}, {0, 30}, {-10, 10}}};
const char* state_field_name(int field);

using RelativeState = std::array<double, kStateFields>;
using StateBins = std::array<int, kStateFields>;

// round((clip(value) - min) / (max - min) * 80)
int state_bin(int field, double value);
// The bin's value: min + bin * (max - min) / 80.
double state_bin_value(int field, int bin);

// The agent's (l, w, h, u, v, dpsi, vx, vy) in the frame of `anchor`: offsets and velocity rotated into it, heading
// difference wrapped.
RelativeState relative_state(const StepState& agent, const Pose& anchor);
// Back to a global state (paper appendix D): x = x_a + u cos psi_a - v sin psi_a, and so on.
StepState global_state(const RelativeState& rel, const Pose& anchor);

struct AgentStateTokens {
  int segment = -1;  // the anchor: an index into the segments the index was built over
  StateBins bins{};
};

// `index` is built over `segments`. Anchor = the nearest segment centre among segments heading within 90 degrees of the agent; FAILED_PRECONDITION
// when no segment qualifies (an empty map).
absl::StatusOr<AgentStateTokens> encode_agent_state(const StepState& agent, const SegmentIndex& index,
                                                   std::span<const MapSegment> segments);
// The global state the tokens stand for.
StepState decode_agent_state(const AgentStateTokens& tokens, std::span<const MapSegment> segments);

}  // namespace ss
