#include "viewer/convert.h"

#include <cmath>

#include "engine/tokens/light.h"

namespace viewer {
namespace {

// Centimetres and milliradians are finer than a screen shows and keep the numbers short.
double cm(double v) { return std::round(v * 100.0) / 100.0; }
double mrad(double v) { return std::round(v * 1000.0) / 1000.0; }

const char* mode_name(pb::Mode m) {
  switch (m) {
    case pb::MODE_MOTION: return "motion";
    case pb::MODE_FULL: return "full";
    case pb::MODE_DENSIFY: return "densify";
    case pb::MODE_LOG: return "log";
    case pb::MODE_IDM: return "idm";
    default: return "unknown";
  }
}

// WOMD ObjectType (1 vehicle, 2 pedestrian, 3 cyclist) onto the model's types; 3: other or unset.
int model_type(ss::ObjectType t) {
  switch (t) {
    case ss::ObjectType::vehicle: return 0;
    case ss::ObjectType::pedestrian: return 1;
    case ss::ObjectType::cyclist: return 2;
    default: return 3;
  }
}

nlohmann::json agent_array(int64_t id, int type, double x, double y, double heading, double length, double width,
                           double speed, int flags) {
  return nlohmann::json::array({id, type, cm(x), cm(y), mrad(heading), cm(length), cm(width), cm(speed), flags});
}

}  // namespace

std::map<int64_t, int> event_flags(const ss::EventMap& map, const ss::StepResult& before, const ss::StepResult& after) {
  ss::StepResult all = after;
  std::map<int64_t, int> type_of;
  for (ss::AgentView& a : all.agents) {
    a.controlled = true;  // tick_events measures the controlled agents: here every one
    type_of[a.id] = a.type;
  }
  std::map<int64_t, int> flags;
  for (const ss::AgentEvents& e : ss::tick_events(map, before, all)) {
    int f = 0;
    if (!e.overlapping.empty()) f |= kOverlap;
    if (e.off_road && type_of[e.agent_id] == 0) f |= kOffRoad;
    if (e.ran_red_light) f |= kRedLight;
    if (f) flags[e.agent_id] = f;
  }
  return flags;
}

ss::StepResult step_result_of(const pb::Tick& tick) {
  ss::StepResult r;
  r.step = tick.step();
  r.time = tick.sim_time();
  for (const pb::Agent& a : tick.agents()) {
    ss::AgentView v;
    v.id = a.id();
    v.type = static_cast<int>(a.type());
    const pb::AgentState& s = a.state();
    v.state = {s.x(), s.y(), s.heading(), s.vx(), s.vy(), s.length(), s.width(), s.height(), true};
    v.controlled = a.controlled();
    v.entered = a.entered();
    r.agents.push_back(v);
  }
  for (const pb::TrafficLight& l : tick.lights()) {
    ss::LightView v;
    v.lane = l.lane();
    v.state = static_cast<ss::LightState>(l.state());
    v.stop_point = {l.stop_point().x(), l.stop_point().y(), l.stop_point().heading()};
    r.lights.push_back(v);
  }
  r.left.assign(tick.left().begin(), tick.left().end());
  return r;
}

nlohmann::json tick_json(const pb::Tick& tick, const std::map<int64_t, int>& flags) {
  nlohmann::json agents = nlohmann::json::array();
  for (const pb::Agent& a : tick.agents()) {
    int f = (a.controlled() ? kControlled : 0) | (a.entered() ? kEntered : 0);
    if (auto it = flags.find(a.id()); it != flags.end()) f |= it->second;
    const pb::AgentState& s = a.state();
    agents.push_back(agent_array(a.id(), static_cast<int>(a.type()), s.x(), s.y(), s.heading(), s.length(), s.width(),
                                 std::hypot(s.vx(), s.vy()), f));
  }
  nlohmann::json lights = nlohmann::json::array();
  for (const pb::TrafficLight& l : tick.lights())
    lights.push_back({l.lane(), cm(l.stop_point().x()), cm(l.stop_point().y()), mrad(l.stop_point().heading()),
                      static_cast<int>(l.state())});
  return {{"type", "tick"},   {"tick", tick.tick()}, {"step", tick.step()}, {"time", tick.sim_time()},
          {"agents", agents}, {"lights", lights},    {"left", std::vector<int64_t>(tick.left().begin(), tick.left().end())}};
}

nlohmann::json session_json(const pb::SessionInfo& info) {
  return {{"id", info.session_id()},
          {"scenario", info.scenario_name()},
          {"mode", mode_name(info.mode())},
          {"tick", info.tick()},
          {"agents", info.num_agents()},
          {"controllers", std::vector<int64_t>(info.controlled_agent_ids().begin(), info.controlled_agent_ids().end())},
          {"tick_hz", info.tick_hz()}};
}

nlohmann::json map_json(const std::vector<ss::MapFeature>& features) {
  nlohmann::json out = nlohmann::json::array();
  for (const ss::MapFeature& f : features) {
    std::vector<double> pts;
    pts.reserve(2 * f.points.size());
    for (const ss::MapPoint& p : f.points) {
      pts.push_back(cm(p.x));
      pts.push_back(cm(p.y));
    }
    out.push_back({{"id", f.id}, {"type", static_cast<int>(f.kind)}, {"subtype", f.subtype}, {"pts", pts}});
  }
  return out;
}

namespace {

// A frame of a scenario as the engine's view, for the events between frames.
ss::StepResult frame_view(const ss::Scenario& s, int frame) {
  ss::StepResult r;
  for (const ss::Track& t : s.tracks) {
    if (frame >= static_cast<int>(t.states.size()) || !t.states[frame].valid) continue;
    const ss::ObjectState& o = t.states[frame];
    ss::AgentView v;
    v.id = t.id;
    v.type = std::min(model_type(t.type), 2);
    v.state = {o.x, o.y, o.heading, o.vx, o.vy, o.length, o.width, o.height, true};
    r.agents.push_back(v);
  }
  if (frame < static_cast<int>(s.signals.size()))
    for (const ss::SignalLaneState& l : s.signals[frame]) {
      if (!l.has_stop_point) continue;
      ss::LightView v;
      v.lane = l.lane;
      v.state = ss::light_state_from_womd(l.state);
      v.stop_point = {l.stop_point.x, l.stop_point.y, 0};
      r.lights.push_back(v);
    }
  return r;
}

nlohmann::json tracks_json(const ss::Scenario& s, const std::vector<std::map<int64_t, int>>* flags) {
  nlohmann::json tracks = nlohmann::json::array();
  for (const ss::Track& t : s.tracks) {
    nlohmann::json states = nlohmann::json::array();
    bool any = false;
    for (size_t f = 0; f < t.states.size(); ++f) {
      const ss::ObjectState& o = t.states[f];
      if (!o.valid) {
        states.push_back(nullptr);
        continue;
      }
      any = true;
      int fl = 0;
      if (flags)
        if (auto it = (*flags)[f].find(t.id); it != (*flags)[f].end()) fl = it->second;
      if (f > 0 && (t.states[f - 1].valid == false)) fl |= kEntered;
      states.push_back({cm(o.x), cm(o.y), mrad(o.heading), cm(o.length), cm(o.width), cm(std::hypot(o.vx, o.vy)), fl});
    }
    if (any) tracks.push_back({{"id", t.id}, {"type", model_type(t.type)}, {"states", states}});
  }
  return tracks;
}

}  // namespace

namespace {

// A light's stop line runs across its lane: the lane's direction at the lane point nearest the stop point (0 when the
// lane is not in the map). Scenario files keep the stop point only; the server's ticks carry the heading.
double lane_heading_at(const ss::Scenario& s, int64_t lane, const ss::MapPoint& p) {
  for (const ss::MapFeature& f : s.map_features) {
    if (f.id != lane || f.kind != ss::MapFeatureKind::lane || f.points.size() < 2) continue;
    size_t best = 0;
    double best_d = 1e300;
    for (size_t i = 0; i + 1 < f.points.size(); ++i) {
      const double d = std::hypot(f.points[i].x - p.x, f.points[i].y - p.y);
      if (d < best_d) best_d = d, best = i;
    }
    return std::atan2(f.points[best + 1].y - f.points[best].y, f.points[best + 1].x - f.points[best].x);
  }
  return 0;
}

}  // namespace

nlohmann::json scenario_json(const ss::Scenario& s, const ss::Scenario* log) {
  const ss::EventMap event_map = ss::event_map_from_scenario(s);
  std::vector<std::map<int64_t, int>> flags(s.num_frames());
  ss::StepResult before;
  for (int f = 0; f < s.num_frames(); ++f) {
    ss::StepResult after = frame_view(s, f);
    flags[f] = event_flags(event_map, before, after);
    before = std::move(after);
  }
  nlohmann::json lights = nlohmann::json::array();
  for (int f = 0; f < s.num_frames(); ++f) {
    nlohmann::json frame = nlohmann::json::array();
    if (f < static_cast<int>(s.signals.size()))
      for (const ss::SignalLaneState& l : s.signals[f])
        if (l.has_stop_point)
          frame.push_back({l.lane, cm(l.stop_point.x), cm(l.stop_point.y), mrad(lane_heading_at(s, l.lane, l.stop_point)),
                           static_cast<int>(ss::light_state_from_womd(l.state))});
    lights.push_back(frame);
  }
  const int sdc = s.sdc_track_index >= 0 && s.sdc_track_index < static_cast<int>(s.tracks.size())
                      ? s.tracks[s.sdc_track_index].id
                      : -1;
  nlohmann::json out = {{"id", s.id},         {"timestamps", s.timestamps}, {"current", s.current_time_index},
                        {"sdc", sdc},         {"map", map_json(s.map_features)}, {"tracks", tracks_json(s, &flags)},
                        {"lights", lights},   {"log", nullptr}};
  if (log) out["log"] = {{"timestamps", log->timestamps}, {"tracks", tracks_json(*log, nullptr)}};
  return out;
}

}  // namespace viewer
