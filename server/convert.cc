#include "server/convert.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace ss::server {
namespace {

absl::Status finite(double v, const std::string& field) {
  if (std::isfinite(v)) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(field, " is ", std::to_string(v), ", not a finite number"));
}

absl::StatusOr<StepState> state_from_proto(const pb::AgentState& s, const std::string& field) {
  const std::pair<double, const char*> values[] = {{s.x(), "x"},   {s.y(), "y"},           {s.heading(), "heading"},
                                                   {s.vx(), "vx"}, {s.vy(), "vy"},         {s.length(), "length"},
                                                   {s.width(), "width"}, {s.height(), "height"}};
  for (const auto& [v, name] : values)
    if (auto st = finite(v, absl::StrCat(field, ".", std::string(name))); !st.ok()) return st;
  StepState out;
  out.x = s.x();
  out.y = s.y();
  out.heading = s.heading();
  out.vx = s.vx();
  out.vy = s.vy();
  out.length = s.length();
  out.width = s.width();
  out.height = s.height();
  out.valid = true;
  return out;
}

pb::AgentState state_to_proto(const StepState& s) {
  pb::AgentState o;
  o.set_x(s.x);
  o.set_y(s.y);
  o.set_heading(s.heading);
  o.set_vx(s.vx);
  o.set_vy(s.vy);
  o.set_length(s.length);
  o.set_width(s.width);
  o.set_height(s.height);
  return o;
}

}  // namespace

pb::Mode mode_to_proto(SessionMode m) { return static_cast<pb::Mode>(static_cast<int>(m)); }

absl::StatusOr<SessionOptions> options_from_proto(const pb::CreateSessionRequest& r) {
  SessionOptions o;
  if (!pb::Mode_IsValid(r.mode()))
    return absl::InvalidArgumentError(absl::StrCat("mode ", std::to_string(r.mode()), " is not a known Mode"));
  o.mode = static_cast<SessionMode>(static_cast<int>(r.mode()));
  o.seed = r.seed();
  if (r.has_sampling()) {
    if (auto st = finite(r.sampling().top_p(), "sampling.top_p"); !st.ok()) return st;
    if (auto st = finite(r.sampling().temperature(), "sampling.temperature"); !st.ok()) return st;
    if (r.sampling().top_p() != 0) o.top_p = r.sampling().top_p();
    if (r.sampling().temperature() != 0) o.temperature = r.sampling().temperature();
    o.motion_reject = !r.sampling().no_motion_reject();
  }
  for (int64_t id : r.controlled_agent_ids()) {
    if (id < INT32_MIN || id > INT32_MAX)
      return absl::InvalidArgumentError(absl::StrCat("controlled_agent_ids: ", std::to_string(id),
                                                     " is not a track id (32-bit)"));
    o.controlled_ids.push_back(static_cast<int32_t>(id));
  }
  o.control_sdc = !r.model_drives_sdc();
  if (auto st = finite(r.roi_radius(), "roi_radius"); !st.ok()) return st;
  if (r.roi_radius() < 0) return absl::InvalidArgumentError("roi_radius must not be negative");
  if (r.roi_radius() > 0) o.roi_radius = r.roi_radius();
  if (r.max_agents() < 0) return absl::InvalidArgumentError("max_agents must not be negative");
  if (r.max_agents() > 0) o.max_agents = r.max_agents();
  if (r.densify_target() < 0) return absl::InvalidArgumentError("densify_target must not be negative");
  o.densify_target = r.densify_target();
  o.agent_counts.assign(r.agent_counts().begin(), r.agent_counts().end());  // the engine checks them
  o.tick_hz = r.tick_hz() == 0 ? 2 : r.tick_hz();  // the engine checks the value
  return o;
}

absl::StatusOr<std::vector<ControlInput>> controls_from_proto(const pb::StepSceneRequest& r) {
  std::vector<ControlInput> out;
  for (int i = 0; i < r.poses_size(); ++i) {
    const pb::ControlledPose& p = r.poses(i);
    const std::string f = absl::StrCat("poses[", std::to_string(i), "] (agent ", std::to_string(p.agent_id()), ")");
    if (auto st = finite(p.x(), f + ".x"); !st.ok()) return st;
    if (auto st = finite(p.y(), f + ".y"); !st.ok()) return st;
    if (auto st = finite(p.heading(), f + ".heading"); !st.ok()) return st;
    ControlInput c{p.agent_id(), p.x(), p.y(), p.heading(), std::nullopt};
    if (p.has_speed()) {
      if (auto st = finite(p.speed(), f + ".speed"); !st.ok()) return st;
      c.speed = p.speed();
    }
    for (const ControlInput& prev : out)
      if (prev.agent_id == c.agent_id)
        return absl::InvalidArgumentError(absl::StrCat(f, ": agent given twice in one request"));
    out.push_back(c);
  }
  return out;
}

absl::StatusOr<InjectRequest> inject_from_proto(const pb::InjectAgentRequest& r) {
  InjectRequest q;
  q.count = r.count();
  if (r.has_type()) {
    if (!pb::AgentType_IsValid(r.type()))
      return absl::InvalidArgumentError(absl::StrCat("type ", std::to_string(r.type()), " is not a known AgentType"));
    q.type = static_cast<int>(r.type());
  }
  if (r.has_near()) {
    if (auto st = finite(r.near().x(), "near.x"); !st.ok()) return st;
    if (auto st = finite(r.near().y(), "near.y"); !st.ok()) return st;
    q.near = Vec2{r.near().x(), r.near().y()};
  }
  if (auto st = finite(r.near_radius(), "near_radius"); !st.ok()) return st;
  if (r.near_radius() > 0) q.near_radius = r.near_radius();
  if (r.has_state()) {
    auto s = state_from_proto(r.state(), "state");
    if (!s.ok()) return s.status();
    q.state = *s;
  }
  return q;
}

absl::StatusOr<StateForceRequest> force_from_proto(const pb::StateForceRequest& r) {
  StateForceRequest q;
  for (int i = 0; i < r.agents_size(); ++i) {
    auto s = state_from_proto(r.agents(i).state(), absl::StrCat("agents[", std::to_string(i), "].state"));
    if (!s.ok()) return s.status();
    q.agents.emplace_back(r.agents(i).agent_id(), *s);
  }
  for (int i = 0; i < r.lights_size(); ++i) {
    if (!pb::LightState_IsValid(r.lights(i).state()))
      return absl::InvalidArgumentError(absl::StrCat("lights[", std::to_string(i), "].state ",
                                                     std::to_string(r.lights(i).state()), " is not a LightState"));
    q.lights.emplace_back(r.lights(i).lane(), static_cast<LightState>(r.lights(i).state()));
  }
  return q;
}

void tick_to_proto(const StepResult& s, int64_t tick, pb::Tick* out) {
  out->set_tick(tick);
  out->set_step(s.step);
  out->set_sim_time(s.time);
  for (const LightView& l : s.lights) {
    pb::TrafficLight* o = out->add_lights();
    o->set_id(l.lane);
    o->set_lane(l.lane);
    o->mutable_stop_point()->set_x(l.stop_point.x);
    o->mutable_stop_point()->set_y(l.stop_point.y);
    o->mutable_stop_point()->set_heading(l.stop_point.heading);
    o->set_state(static_cast<pb::LightState>(static_cast<int>(l.state)));
  }
  for (const AgentView& a : s.agents) {
    pb::Agent* o = out->add_agents();
    o->set_id(a.id);
    o->set_type(static_cast<pb::AgentType>(a.type));
    *o->mutable_state() = state_to_proto(a.state);
    o->set_controlled(a.controlled);
    o->set_entered(a.entered);
  }
  for (int64_t id : s.left) out->add_left(id);
  for (const AgentEvents& e : s.events) {
    pb::AgentEvents* o = out->add_events();
    o->set_agent_id(e.agent_id);
    for (int64_t id : e.overlapping) o->add_overlapping(id);
    o->set_off_road(e.off_road);
    o->set_road_edge_distance(e.road_edge_distance);
    o->set_ran_red_light(e.ran_red_light);
    o->set_red_light_lane(e.red_light_lane);
    o->set_lane_id(e.lane.lane_id);
    o->set_lane_s(e.lane.s);
    o->set_lane_offset(e.lane.offset);
    o->set_lane_heading_error(e.lane.heading_error);
    o->set_progress(e.progress);
  }
}

::grpc::Status to_grpc(const absl::Status& st) {
  if (st.ok()) return ::grpc::Status::OK;
  return ::grpc::Status(static_cast<::grpc::StatusCode>(static_cast<int>(st.code())), std::string(st.message()));
}

void map_to_proto(const std::vector<MapFeature>& map, pb::CreateSessionResponse* out) {
  for (const MapFeature& f : map) {
    pb::MapFeature* o = out->add_map();
    o->set_id(f.id);
    // MapFeatureType lists the kinds in MapFeatureKind's order.
    o->set_type(static_cast<pb::MapFeatureType>(static_cast<int>(f.kind)));
    o->set_subtype(f.subtype);
    for (const MapPoint& p : f.points) {
      o->add_x(p.x);
      o->add_y(p.y);
    }
    if (f.kind != MapFeatureKind::lane) continue;
    for (int64_t id : f.lane.entry_lanes) o->add_entry_lanes(id);
    for (int64_t id : f.lane.exit_lanes) o->add_exit_lanes(id);
    o->set_speed_limit_mph(f.lane.speed_limit_mph);
  }
}

}  // namespace ss::server
