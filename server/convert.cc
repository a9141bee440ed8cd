#include "server/convert.h"

#include "absl/strings/str_cat.h"

namespace ss::server {
namespace {

// Decoding only: the engine checks every value once, at its entry (Session::create, tick, inject, state_force).
// What stays here is what the engine's types cannot hold: an id beyond 32 bits, a light state beyond a byte.

StepState state_from_proto(const pb::AgentState& s) {
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
  // Zero is proto3's "not given": the engine's default stays. Any other value goes to the engine, which checks it.
  o.mode = static_cast<SessionMode>(static_cast<int>(r.mode()));
  o.seed = r.seed();
  if (r.has_sampling()) {
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
  if (r.roi_radius() != 0) o.roi_radius = r.roi_radius();
  if (r.max_agents() != 0) o.max_agents = r.max_agents();
  o.densify_target = r.densify_target();
  o.agent_counts.assign(r.agent_counts().begin(), r.agent_counts().end());
  o.tick_hz = r.tick_hz() == 0 ? 2 : r.tick_hz();
  return o;
}

std::vector<ControlInput> controls_from_proto(const pb::StepSceneRequest& r) {
  std::vector<ControlInput> out;
  for (const pb::ControlledPose& p : r.poses()) {
    ControlInput c{p.agent_id(), p.x(), p.y(), p.heading(), std::nullopt};
    if (p.has_speed()) c.speed = p.speed();
    out.push_back(c);
  }
  return out;
}

InjectRequest inject_from_proto(const pb::InjectAgentRequest& r) {
  InjectRequest q;
  q.count = r.count();
  if (r.has_type()) q.type = static_cast<int>(r.type());
  if (r.has_near()) q.near = Vec2{r.near().x(), r.near().y()};
  if (r.near_radius() != 0) q.near_radius = r.near_radius();
  if (r.has_state()) q.state = state_from_proto(r.state());
  return q;
}

absl::StatusOr<StateForceRequest> force_from_proto(const pb::StateForceRequest& r) {
  StateForceRequest q;
  for (const pb::ForcedAgent& a : r.agents()) q.agents.emplace_back(a.agent_id(), state_from_proto(a.state()));
  for (int i = 0; i < r.lights_size(); ++i) {
    const int state = r.lights(i).state();
    if (state < 0 || state > 255)  // LightState is a byte: the engine sees every value that fits
      return absl::InvalidArgumentError(absl::StrCat("lights[", std::to_string(i), "].state ", std::to_string(state),
                                                     " is not a LightState"));
    q.lights.emplace_back(r.lights(i).lane(), static_cast<LightState>(state));
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
