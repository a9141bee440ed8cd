#include "offline/eval/model_rollout.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>

#include "absl/strings/str_cat.h"
#include "offline/eval/baselines.h"
#include "engine/map/focus.h"
#include "engine/sim/rollout_export.h"
#include "engine/tokens/fidelity.h"
#include "engine/tokens/resample.h"

namespace ss {

Scenario history_only(const Scenario& s) {
  const size_t frames = static_cast<size_t>(s.current_time_index) + 1;
  Scenario h = s;
  h.timestamps.resize(std::min(frames, h.timestamps.size()));
  for (Track& t : h.tracks) t.states.resize(std::min(frames, t.states.size()));
  h.signals.resize(std::min(frames, h.signals.size()));
  h.laser_data.clear(), h.camera_tokens.clear();  // sensor data: no session reads it
  return h;
}

absl::StatusOr<std::vector<StepResult>> run_model_rollout(std::shared_ptr<const Model> model,
                                                          std::shared_ptr<const Scenario> scenario,
                                                          std::shared_ptr<const MapContext> map,
                                                          const SessionOptions& options, SdcRule sdc_rule, int steps,
                                                          RolloutInputs* inputs) {
  const int now = scenario->current_time_index;
  if (now % kFramesPerStep != 0)
    return absl::InvalidArgumentError(absl::StrCat("scenario ", scenario->id, ": current frame ", now,
                                                   " is not a 2 Hz step (a multiple of ", kFramesPerStep, ")"));
  SessionOptions o = options;
  o.controlled_ids.clear();
  o.control_sdc = sdc_rule == SdcRule::log;
  // The rule modes replay or follow the log's future, so only they are given it.
  const bool rules = o.mode == SessionMode::log || o.mode == SessionMode::idm;
  auto history = rules ? scenario : std::make_shared<const Scenario>(history_only(*scenario));
  if (inputs) *inputs = {history, o, {}};
  auto session = Session::create(std::move(model), history, std::move(map), o);
  if (!session.ok())
    return absl::Status(session.status().code(), absl::StrCat("scenario ", scenario->id, ": ", session.status().message()));
  if (steps < 0) steps = (scenario->num_frames() - 1 - now + kFramesPerStep - 1) / kFramesPerStep;
  std::vector<StepResult> results = {(*session)->current()};
  const Track* sdc = sdc_rule == SdcRule::log && scenario->sdc_track_index >= 0
                         ? &scenario->tracks[scenario->sdc_track_index]
                         : nullptr;
  for (int i = 0; i < steps; ++i) {
    std::vector<ControlInput> controls;
    const int frame = ((*session)->step_index() + 1) * kFramesPerStep;
    if (sdc && frame < static_cast<int>(sdc->states.size()) && sdc->states[frame].valid) {
      const bool controlled = std::any_of(results.back().agents.begin(), results.back().agents.end(),
                                          [&](const AgentView& a) { return a.id == sdc->id && a.controlled; });
      if (controlled) {
        const ObjectState& st = sdc->states[frame];
        controls.push_back({sdc->id, st.x, st.y, st.heading, std::nullopt});
      }
    }
    if (inputs) inputs->controls.push_back(controls);
    auto r = (*session)->step(controls);
    if (!r.ok())
      return absl::Status(r.status().code(),
                          absl::StrCat("scenario ", scenario->id, " step ", i + 1, ": ", r.status().message()));
    results.push_back(std::move(*r));
  }
  return results;
}

RolloutScene rollout_scene(const Scenario& s, const std::vector<int>& tracks, const std::vector<StepResult>& steps,
                           bool match_generated) {
  const int now = s.current_time_index;
  const int frames = s.num_frames();
  RolloutScene out;
  out.scene = log_scene(s, tracks);
  if (steps.empty()) return out;

  // Each agent at 10 Hz from the current frame on.
  std::map<int64_t, std::vector<StepState>> frames_of;
  std::map<int64_t, int> types;
  std::vector<int64_t> order;  // first appearance
  for (RolloutAgent& a : rollout_agents(steps)) {
    order.push_back(a.id), types[a.id] = a.type;
    frames_of[a.id] = std::move(a.frames);
  }
  auto sim_at = [&](int64_t id, int f) -> const StepState* {
    auto it = frames_of.find(id);
    const int j = f - now;
    if (it == frames_of.end() || j < 0 || j >= static_cast<int>(it->second.size()) || !it->second[j].valid) return nullptr;
    return &it->second[j];
  };

  std::set<int64_t> track_ids;
  for (const Track& t : s.tracks) track_ids.insert(t.id);
  // Which agent drives each track: its own id when the session has it; in full mode, a generated agent.
  std::vector<int64_t> driver(tracks.size(), -1);
  std::vector<bool> generated_pair(tracks.size(), false);
  for (size_t k = 0; k < tracks.size(); ++k)
    if (frames_of.count(s.tracks[tracks[k]].id)) driver[k] = s.tracks[tracks[k]].id;
  std::set<int64_t> used;
  if (match_generated) {
    std::vector<std::tuple<double, size_t, size_t>> pairs;  // distance, track k, agent index at the first step
    const auto& first = steps[0].agents;
    for (size_t k = 0; k < tracks.size(); ++k) {
      if (driver[k] >= 0) continue;
      const Track& t = s.tracks[tracks[k]];
      if (model_type(t.type) < 0) continue;
      ++out.to_match;
      for (size_t a = 0; a < first.size(); ++a)
        if (!track_ids.count(first[a].id) && first[a].type == model_type(t.type))
          pairs.emplace_back(std::hypot(first[a].state.x - t.states[now].x, first[a].state.y - t.states[now].y), k, a);
    }
    std::sort(pairs.begin(), pairs.end());
    double total = 0;
    for (const auto& [d, k, a] : pairs) {
      if (driver[k] >= 0 || used.count(first[a].id)) continue;
      driver[k] = first[a].id;
      generated_pair[k] = true;
      used.insert(first[a].id);
      total += d;
      ++out.matched;
    }
    out.match_distance = out.matched ? total / out.matched : 0.0;
  }

  for (size_t k = 0; k < tracks.size(); ++k) {
    const ObjectState& log_now = s.tracks[tracks[k]].states[now];
    std::vector<BoxState>& st = out.scene.objects[k].states;
    double length = log_now.length, width = log_now.width, height = log_now.height;
    if (generated_pair[k]) {
      const StepState& g = *sim_at(driver[k], now);
      length = g.length, width = g.width, height = g.height;
      // The logged history, moved rigidly so its current pose becomes the generated agent's.
      const double turn = g.heading - log_now.heading;
      for (int f = 0; f <= now; ++f) {
        BoxState& b = st[f];
        const Vec2 p = rotate({b.x - log_now.x, b.y - log_now.y}, turn);
        b.x = g.x + p.x, b.y = g.y + p.y, b.heading = wrap_angle(b.heading + turn);
      }
      st[now].length = length, st[now].width = width, st[now].height = height;
    }
    int last = now;
    for (int f = now + 1; f < frames; ++f) {
      const StepState* p = driver[k] >= 0 ? sim_at(driver[k], f) : nullptr;
      if (!p) break;  // retired agents do not come back
      st[f] = {p->x, p->y, log_now.z, p->heading, length, width, height, true};
      last = f;
      ++out.driven_frames;
    }
    double vx = log_now.vx, vy = log_now.vy;
    if (const StepState* p = driver[k] >= 0 ? sim_at(driver[k], last) : nullptr) vx = p->vx, vy = p->vy;
    extend_constant_velocity(st, last, vx, vy);  // copies the last state: its size and height too
    out.filled_frames += frames - 1 - last;
  }

  // Agents the model created that stand in for no track: obstacles while present.
  for (int64_t id : order) {
    if (track_ids.count(id) || used.count(id)) continue;
    SceneObject o;
    o.id = id;
    o.type = object_type_of(types[id]);
    o.states.resize(frames);
    for (int f = now; f < frames; ++f)
      if (const StepState* p = sim_at(id, f)) o.states[f] = {p->x, p->y, 0, p->heading, p->length, p->width, p->height, true};
    out.scene.objects.push_back(std::move(o));
  }
  return out;
}

std::vector<InitialAgent> generated_initial_agents(const StepResult& first) {
  std::vector<InitialAgent> out;
  for (const AgentView& a : first.agents) {
    if (a.controlled) continue;
    const StepState& s = a.state;
    out.push_back({s.x, s.y, s.heading, s.length, s.width, s.vx, s.vy, object_type_of(a.type)});
  }
  return out;
}

std::vector<InitialAgent> log_initial_agents(const Scenario& s) {
  std::vector<InitialAgent> out;
  for (int i : sim_agent_tracks(s)) {
    const Track& t = s.tracks[i];
    if (i == s.sdc_track_index || model_type(t.type) < 0) continue;
    const ObjectState& o = t.states[s.current_time_index];
    out.push_back({o.x, o.y, o.heading, o.length, o.width, o.vx, o.vy, t.type});
  }
  return out;
}

Pose mmd_frame(const Scenario& s) {
  const int now = s.current_time_index;
  if (s.sdc_track_index >= 0 && s.tracks[s.sdc_track_index].states[now].valid) {
    const ObjectState& o = s.tracks[s.sdc_track_index].states[now];
    return {o.x, o.y, o.heading};
  }
  const Vec2 c = scenario_focus(s);
  return {c.x, c.y, 0.0};
}

}  // namespace ss
