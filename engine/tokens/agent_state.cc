#include "engine/tokens/agent_state.h"

#include <algorithm>
#include <cmath>

namespace ss {

const char* state_field_name(int field) {
  static constexpr const char* kNames[kStateFields] = {"length", "width", "height", "u", "v", "heading", "vx", "vy"};
  return field >= 0 && field < kStateFields ? kNames[field] : "invalid";
}

int state_bin(int field, double value) {
  const FieldRange r = kStateRanges[field];
  double f = (std::clamp(value, r.min, r.max) - r.min) / (r.max - r.min);
  return static_cast<int>(std::lround(f * (kStateBins - 1)));
}

double state_bin_value(int field, int bin) {
  const FieldRange r = kStateRanges[field];
  return r.min + bin * (r.max - r.min) / (kStateBins - 1);
}

RelativeState relative_state(const StepState& agent, const Pose& anchor) {
  Vec2 offset = to_local(anchor, {agent.x, agent.y});
  Vec2 velocity = rotate({agent.vx, agent.vy}, -anchor.heading);
  return {agent.length, agent.width,  agent.height, offset.x, offset.y, wrap_angle(agent.heading - anchor.heading),
          velocity.x,   velocity.y};
}

StepState global_state(const RelativeState& rel, const Pose& anchor) {
  StepState s;
  Vec2 p = to_global(anchor, {rel[kFieldU], rel[kFieldV]});
  Vec2 v = rotate({rel[kFieldVx], rel[kFieldVy]}, anchor.heading);
  s.x = p.x;
  s.y = p.y;
  s.heading = wrap_angle(anchor.heading + rel[kFieldHeading]);
  s.vx = v.x;
  s.vy = v.y;
  s.length = rel[kFieldLength];
  s.width = rel[kFieldWidth];
  s.height = rel[kFieldHeight];
  s.valid = true;
  return s;
}

absl::StatusOr<AgentStateTokens> encode_agent_state(const StepState& agent, const SegmentIndex& index,
                                                   std::span<const MapSegment> segments) {
  AgentStateTokens tokens;
  tokens.segment = index.nearest({agent.x, agent.y, agent.heading});
  if (tokens.segment < 0)
    return absl::FailedPreconditionError("no map segment heads within 90 degrees of the agent: the map is empty");
  RelativeState rel = relative_state(agent, segments[tokens.segment].pose);
  for (int f = 0; f < kStateFields; ++f) tokens.bins[f] = state_bin(f, rel[f]);
  return tokens;
}

StepState decode_agent_state(const AgentStateTokens& tokens, std::span<const MapSegment> segments) {
  RelativeState rel;
  for (int f = 0; f < kStateFields; ++f) rel[f] = state_bin_value(f, tokens.bins[f]);
  return global_state(rel, segments[tokens.segment].pose);
}

}  // namespace ss
