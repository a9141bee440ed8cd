#include "engine/sim/token_builders.h"

#include <algorithm>
#include <cmath>

namespace ss {

int anchor_segment(const SegmentIndex& index, const StepState& s) {
  int seg = index.nearest({s.x, s.y, s.heading});
  if (seg < 0) seg = index.nearest({s.x, s.y, s.heading}, 2 * kPi);  // no segment heads its way: any
  return seg;
}

std::array<float, kRsFields> scaled_relative_state(const StateBins& bins) {
  std::array<float, kRsFields> out{};
  for (int f = 0; f < kRsFields; ++f) out[f] = 2.0f * bins[f] / (kRsBins - 1) - 1.0f;
  return out;
}

StateBins relative_state_bins(const StepState& s, const Pose& anchor) {
  StateBins bins{};
  const RelativeState rel = relative_state(s, anchor);
  for (int f = 0; f < kRsFields; ++f) bins[f] = state_bin(f, rel[f]);
  return bins;
}

DecoderToken light_token(int step, int index, const TokenLight& light, LightState state) {
  DecoderToken t;
  t.kind = TokenKind::light;
  t.step = step;
  t.object = light_object(index);
  t.has_pose = true;
  t.pose = light.pose;
  t.light_slot = index;
  t.light_state = static_cast<int>(state);
  t.map_id = light.map_id;
  return t;
}

void agent_group_tokens(int step, const TokenAgent& a, int order, int seg, const MapSegment& anchor,
                        std::vector<DecoderToken>& out) {
  DecoderToken t;
  t.step = step;
  t.object = a.id;
  t.agent_slot = a.slot;
  t.agent_type = a.type;
  t.kind = TokenKind::soa;
  t.intra_index = 4 * order;
  out.push_back(t);
  t.kind = TokenKind::type;
  t.intra_index = 4 * order + 1;
  out.push_back(t);
  t.kind = TokenKind::map_segment;
  t.intra_index = 4 * order + 2;
  t.has_pose = true;
  t.pose = anchor.pose;
  t.map_id = seg;
  out.push_back(t);
  t.kind = TokenKind::relative_state;
  t.intra_index = 4 * order + 3;
  t.pose = {a.state.x, a.state.y, a.state.heading};
  t.relative_state = scaled_relative_state(relative_state_bins(a.state, anchor.pose));
  out.push_back(t);
}

DecoderToken agent_motion_token(int step, const TokenAgent& a) {
  DecoderToken t;
  t.kind = TokenKind::motion;
  t.step = step;
  t.object = a.id;
  t.has_pose = true;
  t.pose = {a.state.x, a.state.y, a.state.heading};
  t.agent_slot = a.slot;
  t.agent_type = a.type;
  t.motion_action = a.last_motion;
  const Vec2 v = rotate({a.state.vx, a.state.vy}, -a.state.heading);
  t.motion_state = {static_cast<float>(v.x / 10), static_cast<float>(v.y / 10), static_cast<float>(a.state.length / 5),
                    static_cast<float>(a.state.width / 2), static_cast<float>(a.state.height / 2)};
  return t;
}

DecoderToken sos_token(int step) {
  DecoderToken t;
  t.kind = TokenKind::sos;
  t.step = step;
  return t;
}

DecoderToken eos_token(int step) {
  DecoderToken t;
  t.kind = TokenKind::eos;
  t.step = step;
  return t;
}

std::vector<TokenLight> scenario_lights(const Scenario& s, int frame, std::span<const MapSegment> segments,
                                        const SegmentIndex& index, int max_lights) {
  std::vector<TokenLight> lights;
  if (frame < 0 || frame >= static_cast<int>(s.signals.size()) || segments.empty()) return lights;
  std::vector<SignalLaneState> now = s.signals[frame];
  std::sort(now.begin(), now.end(), [](const auto& a, const auto& b) { return a.lane < b.lane; });
  for (const SignalLaneState& ls : now) {
    if (static_cast<int>(lights.size()) >= max_lights) break;
    TokenLight l;
    l.lane = ls.lane;
    const Vec2 stop{ls.stop_point.x, ls.stop_point.y};
    int best = -1;
    double best_d = INFINITY;
    for (size_t j = 0; j < segments.size(); ++j) {
      const MapSegment& seg = segments[j];
      const double d = distance(stop, {seg.pose.x, seg.pose.y});
      if (seg.kind == MapFeatureKind::lane && seg.feature_id == ls.lane && d < best_d) best = static_cast<int>(j), best_d = d;
    }
    if (best < 0) best = index.nearest({stop.x, stop.y, 0}, 2 * kPi);
    l.map_id = best;
    l.pose = {stop.x, stop.y, segments[best].pose.heading};
    lights.push_back(l);
  }
  return lights;
}

LightState log_light_state(const Scenario& s, int64_t lane, int frame) {
  if (frame >= 0 && frame < static_cast<int>(s.signals.size()))
    for (const SignalLaneState& ls : s.signals[frame])
      if (ls.lane == lane) return light_state_from_womd(ls.state);
  return LightState::unknown;
}

}  // namespace ss
