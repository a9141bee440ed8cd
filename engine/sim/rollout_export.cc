#include "engine/sim/rollout_export.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "absl/strings/str_cat.h"
#include "engine/geometry/geometry.h"
#include "engine/tokens/fidelity.h"

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

// The z of the lane point nearest to (x, y) in the plane (any feature's points when the map has no lanes; 0 for an
// empty map): the model has no height, and a lane is where a new agent or a stop line stands.
double map_z_near(const Scenario& s, double x, double y) {
  double best = std::numeric_limits<double>::infinity(), z = 0;
  for (bool lanes_only : {true, false}) {
    for (const MapFeature& f : s.map_features) {
      if (lanes_only && f.kind != MapFeatureKind::lane) continue;
      for (const MapPoint& p : f.points)
        if (const double d = std::hypot(p.x - x, p.y - y); d < best) best = d, z = p.z;
    }
    if (std::isfinite(best)) break;
  }
  return z;
}

// The track's last valid z at or before `frame`; NaN when it has none.
double last_logged_z(const Track& t, int frame) {
  for (int f = std::min<int>(frame, static_cast<int>(t.states.size()) - 1); f >= 0; --f)
    if (t.states[f].valid) return t.states[f].z;
  return std::nan("");
}

ObjectState object_state(const StepState& s, double z) {
  return {s.x, s.y, z, static_cast<float>(s.length), static_cast<float>(s.width), static_cast<float>(s.height),
          static_cast<float>(wrap_angle(s.heading)), static_cast<float>(s.vx), static_cast<float>(s.vy), true};
}

}  // namespace

std::vector<RolloutAgent> rollout_agents(const std::vector<StepResult>& steps) {
  std::map<int64_t, size_t> index;
  std::vector<RolloutAgent> agents;
  std::vector<std::vector<StepState>> at_steps;
  for (size_t k = 0; k < steps.size(); ++k)
    for (const AgentView& a : steps[k].agents) {
      auto [it, added] = index.emplace(a.id, agents.size());
      if (added) {
        agents.push_back({a.id, a.type, {}});
        at_steps.emplace_back(steps.size());
      }
      at_steps[it->second][k] = a.state;
      at_steps[it->second][k].valid = true;
    }
  for (size_t i = 0; i < agents.size(); ++i) agents[i].frames = upsample_states(at_steps[i]);
  return agents;
}

absl::StatusOr<Scenario> rollout_to_scenario(const Scenario& source, const std::vector<StepResult>& steps) {
  const int now = source.current_time_index;
  if (steps.empty()) return absl::InvalidArgumentError(absl::StrCat("scenario ", source.id, ": a rollout has no step"));
  if (steps[0].step * kFramesPerStep != now || now >= source.num_frames())
    return absl::InvalidArgumentError(absl::StrCat("scenario ", source.id, ": the rollout starts at frame ",
                                                   steps[0].step * kFramesPerStep, ", not at the current frame ", now,
                                                   " of ", source.num_frames()));
  const int future = (static_cast<int>(steps.size()) - 1) * kFramesPerStep;
  const int frames = now + 1 + future;

  Scenario out = source;
  out.timestamps.resize(now + 1);
  for (int j = 1; j <= future; ++j) out.timestamps.push_back(source.timestamps[now] + j * kFrameSeconds);

  const std::vector<RolloutAgent> agents = rollout_agents(steps);
  std::map<int64_t, const RolloutAgent*> by_id;
  for (const RolloutAgent& a : agents) by_id[a.id] = &a;
  std::set<int64_t> log_ids;
  for (Track& t : out.tracks) {
    log_ids.insert(t.id);
    t.states.resize(now + 1);
    t.states.resize(frames);  // invalid after the current frame unless the session has the agent
    auto it = by_id.find(t.id);
    if (it == by_id.end()) continue;
    double z = last_logged_z(t, now);
    for (int j = 1; j <= future; ++j) {
      const StepState& s = it->second->frames[j];
      if (!s.valid) continue;
      if (std::isnan(z)) z = map_z_near(source, s.x, s.y);
      t.states[now + j] = object_state(s, z);
    }
  }
  for (const RolloutAgent& a : agents) {
    if (log_ids.count(a.id)) continue;
    if (a.id > std::numeric_limits<int32_t>::max())
      return absl::InvalidArgumentError(absl::StrCat("scenario ", source.id, ": generated agent id ", a.id,
                                                     " does not fit a WOMD track id (int32)"));
    Track t;
    t.id = static_cast<int32_t>(a.id);
    t.type = object_type_of(a.type);
    t.states.resize(frames);
    double z = std::nan("");
    for (int j = 0; j <= future; ++j) {
      const StepState& s = a.frames[j];
      if (!s.valid) continue;
      if (std::isnan(z)) z = map_z_near(source, s.x, s.y);
      // The current frame is the log's: an agent the model created there appears from the next frame on.
      if (j > 0) t.states[now + j] = object_state(s, z);
    }
    // An agent created at the current step and gone by the next (retired, or out of the region) has no frame to
    // show: a track valid nowhere would only confuse readers (WOMD tracks have a valid state).
    if (std::none_of(t.states.begin(), t.states.end(), [](const ObjectState& o) { return o.valid; })) continue;
    out.tracks.push_back(std::move(t));
  }

  // Signals: the log's up to the current frame, then the model's lights, each held until the next step.
  const bool any_light = std::any_of(steps.begin(), steps.end(), [](const StepResult& r) { return !r.lights.empty(); });
  if (source.signals.empty() && !any_light) {
    out.signals.clear();
  } else {
    out.signals.resize(now + 1);
    std::map<int64_t, double> stop_z;  // lane -> z of its latest logged stop point
    for (int f = 0; f <= now && f < static_cast<int>(source.signals.size()); ++f)
      for (const SignalLaneState& s : source.signals[f])
        if (s.has_stop_point) stop_z[s.lane] = s.stop_point.z;
    for (int j = 1; j <= future; ++j) {
      std::vector<SignalLaneState> lanes;
      for (const LightView& l : steps[j / kFramesPerStep].lights) {
        auto z = stop_z.find(l.lane);
        if (z == stop_z.end()) z = stop_z.emplace(l.lane, map_z_near(source, l.stop_point.x, l.stop_point.y)).first;
        lanes.push_back({l.lane, womd_state(l.state), {l.stop_point.x, l.stop_point.y, z->second}, true});
      }
      out.signals.push_back(std::move(lanes));
    }
  }
  return out;
}

}  // namespace ss
