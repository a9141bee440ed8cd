#include "engine/sim/rollout_export.h"

#include <map>

#include "engine/tokens/fidelity.h"
#include "engine/tokens/resample.h"

namespace ss {
namespace {

SignalState womd_state(LightState s) {
  switch (s) {
    case LightState::green: return SignalState::go;
    case LightState::yellow: return SignalState::caution;
    case LightState::red: return SignalState::stop;
    case LightState::unknown: break;
  }
  return SignalState::unknown;
}

}  // namespace

Scenario rollout_to_scenario(const Scenario& source, const std::vector<StepResult>& steps) {
  Scenario out;
  out.id = source.id + "-rollout";
  out.map_features = source.map_features;
  if (steps.empty()) return out;
  const int n = static_cast<int>(steps.size());
  const int frames = (n - 1) * kFramesPerStep + 1;
  for (int f = 0; f < frames; ++f) out.timestamps.push_back(steps[0].time + f * kFrameSeconds);

  // Each agent's 2 Hz states, in order of first appearance.
  std::map<int64_t, int> index;
  std::vector<std::vector<StepState>> states;
  std::vector<int> types;
  for (int t = 0; t < n; ++t)
    for (const AgentView& a : steps[t].agents) {
      auto [it, added] = index.emplace(a.id, static_cast<int>(states.size()));
      if (added) {
        states.emplace_back(n);
        types.push_back(a.type);
        Track track;
        track.id = static_cast<int32_t>(a.id);
        track.type = object_type_of(a.type);
        out.tracks.push_back(track);
        if (a.controlled && out.sdc_track_index < 0) out.sdc_track_index = it->second;
      }
      states[it->second][t] = a.state;
      states[it->second][t].valid = true;
    }
  for (size_t i = 0; i < out.tracks.size(); ++i) {
    for (const StepState& s : upsample_states(states[i])) {
      ObjectState o;
      if (s.valid)
        o = {s.x, s.y, 0, static_cast<float>(s.length), static_cast<float>(s.width), static_cast<float>(s.height),
             static_cast<float>(wrap_angle(s.heading)), static_cast<float>(s.vx), static_cast<float>(s.vy), true};
      out.tracks[i].states.push_back(o);
    }
  }
  // Lights hold their state between model steps.
  out.signals.resize(frames);
  for (int f = 0; f < frames; ++f)
    for (const LightView& l : steps[f / kFramesPerStep].lights) {
      SignalLaneState s;
      s.lane = l.lane;
      s.state = womd_state(l.state);
      s.stop_point = {l.stop_point.x, l.stop_point.y, 0};
      s.has_stop_point = true;
      out.signals[f].push_back(s);
    }
  return out;
}

}  // namespace ss
