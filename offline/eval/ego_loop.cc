#include "offline/eval/ego_loop.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "absl/strings/str_cat.h"
#include "engine/tokens/resample.h"

namespace ss {
namespace {

constexpr double kSlowFactor = 0.6, kFastFactor = 1.3;
constexpr double kLaneSpacing = 2.0;  // python/scenestreamer/road.py: lane centres resampled every 2 m


double speed_along(const StepState& s) { return s.vx * std::cos(s.heading) + s.vy * std::sin(s.heading); }

// Indices of the at most k points within `radius` of `centre`, nearest first (road.py's RoadMap.nearest).
std::vector<size_t> nearest(const std::vector<Vec2>& points, Vec2 centre, double radius, size_t k) {
  std::vector<std::pair<double, size_t>> inside;
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec2 d = points[i] - centre;
    const double d2 = d.x * d.x + d.y * d.y;
    if (d2 <= radius * radius) inside.push_back({d2, i});
  }
  std::stable_sort(inside.begin(), inside.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<size_t> out;
  for (size_t i = 0; i < inside.size() && i < k; ++i) out.push_back(inside[i].second);
  return out;
}

// Signed distance from a point to a box: negative inside (the depth to the nearest side).
double point_box_distance(Vec2 p, const Box& b) {
  const Vec2 q = to_local(b.pose, p);
  const double dx = std::abs(q.x) - b.length / 2, dy = std::abs(q.y) - b.width / 2;
  if (dx <= 0 && dy <= 0) return std::max(dx, dy);
  return norm({std::max(dx, 0.0), std::max(dy, 0.0)});
}

Vec2 front_point(const StepState& s) {
  return {s.x + s.length / 2 * std::cos(s.heading), s.y + s.length / 2 * std::sin(s.heading)};
}

// Whether two boxes can overlap at all: their centres within the sum of their half diagonals.
bool may_touch(const StepState& a, const StepState& b) {
  return distance({a.x, a.y}, {b.x, b.y}) <= (norm({a.length, a.width}) + norm({b.length, b.width})) / 2;
}

}  // namespace

const char* ego_policy_name(EgoPolicy p) {
  switch (p) {
    case EgoPolicy::log: return "log";
    case EgoPolicy::slow: return "slow";
    case EgoPolicy::fast: return "fast";
    case EgoPolicy::cruise: return "cruise";
  }
  return "invalid";
}

std::optional<EgoPolicy> ego_policy_from_name(const std::string& name) {
  for (EgoPolicy p : {EgoPolicy::log, EgoPolicy::slow, EgoPolicy::fast, EgoPolicy::cruise})
    if (name == ego_policy_name(p)) return p;
  return std::nullopt;
}

const char* ego_collision_name(EgoCollision c) {
  switch (c) {
    case EgoCollision::none: return "none";
    case EgoCollision::rear_end: return "rear_end";
    case EgoCollision::ego_at_fault: return "ego_at_fault";
    case EgoCollision::side: return "side";
  }
  return "invalid";
}

absl::StatusOr<EgoDriver> EgoDriver::create(const Scenario& scenario, EgoPolicy policy) {
  const int now = scenario.current_time_index;
  if (scenario.sdc_track_index < 0)
    return absl::FailedPreconditionError(absl::StrCat("scenario ", scenario.id, " names no SDC: no ego to drive"));
  const Track& sdc = scenario.tracks[scenario.sdc_track_index];
  if (now < 0 || now >= static_cast<int>(sdc.states.size()) || !sdc.states[now].valid)
    return absl::FailedPreconditionError(absl::StrCat("scenario ", scenario.id, ": the SDC has no state at the current frame ", now));
  EgoDriver d;
  d.policy_ = policy;
  d.scenario_ = &scenario;
  d.id_ = sdc.id;
  d.path_ = logged_path(sdc);
  double speed = 0;
  for (size_t f = 0; f < sdc.states.size(); ++f) {
    d.frame_s_.push_back(path_s_at_frame(d.path_, static_cast<int>(f)));
    if (sdc.states[f].valid) speed = std::hypot(sdc.states[f].vx, sdc.states[f].vy);
    d.frame_speed_.push_back(speed);
  }
  if (policy == EgoPolicy::cruise)
    for (const MapFeature& f : scenario.map_features) {
      if (f.kind != MapFeatureKind::lane) continue;
      std::vector<Vec2> p;
      for (const MapPoint& q : f.points)
        if (p.empty() || distance({q.x, q.y}, p.back()) > 0) p.push_back({q.x, q.y});
      if (p.size() < 2) continue;
      // Points every kLaneSpacing metres from the first, and the last (road.py's _resample).
      std::vector<double> s = {0};
      for (size_t i = 1; i < p.size(); ++i) s.push_back(s.back() + distance(p[i], p[i - 1]));
      std::vector<double> at;
      for (double a = 0; a < s.back(); a += kLaneSpacing) at.push_back(a);
      at.push_back(s.back());
      for (double a : at) {
        const size_t j = std::min<size_t>(std::upper_bound(s.begin(), s.end(), a) - s.begin() - 1, p.size() - 2);
        const double len = s[j + 1] - s[j];
        const Vec2 dir = (1 / len) * (p[j + 1] - p[j]);
        d.lane_points_.push_back(p[j] + (a - s[j]) * dir);
        d.lane_dirs_.push_back(dir);
      }
    }
  return d;
}

std::optional<ControlInput> EgoDriver::next(const StepResult& now, int next_step) const {
  const auto ego = std::find_if(now.agents.begin(), now.agents.end(), [&](const AgentView& a) { return a.id == id_; });
  if (ego == now.agents.end()) return std::nullopt;
  const Track& sdc = scenario_->tracks[scenario_->sdc_track_index];
  const int frame = next_step * kFramesPerStep;
  switch (policy_) {
    case EgoPolicy::log: {
      if (frame >= static_cast<int>(sdc.states.size()) || !sdc.states[frame].valid) return std::nullopt;
      const ObjectState& st = sdc.states[frame];
      return ControlInput{id_, st.x, st.y, st.heading, std::nullopt};
    }
    case EgoPolicy::slow:
    case EgoPolicy::fast: {
      const double factor = policy_ == EgoPolicy::slow ? kSlowFactor : kFastFactor;
      const int start = scenario_->current_time_index;
      const double w = start + factor * (frame - start);  // the log's frame this one is warped to
      const int last = path_.frame.empty() ? start : path_.frame.back();
      double s, v;
      if (w >= last) {
        v = frame_speed_[last];
        s = frame_s_[last] + v * (w - last) * 0.1;  // frames are 0.1 s apart
      } else {
        const int f0 = static_cast<int>(std::floor(w));
        const double t = w - f0;
        s = (1 - t) * frame_s_[f0] + t * frame_s_[f0 + 1];
        v = (1 - t) * frame_speed_[f0] + t * frame_speed_[f0 + 1];
      }
      const Pose p = path_pose(path_, s);
      return ControlInput{id_, p.x, p.y, wrap_angle(p.heading), factor * v};
    }
    case EgoPolicy::cruise: {
      std::vector<StepState> others;
      for (const AgentView& a : now.agents)
        if (a.id != id_) others.push_back(a.state);
      const auto [accel, yaw_rate] = cruise_action(ego->state, others, lane_points_, lane_dirs_);
      return advance_pose(id_, ego->state, accel, yaw_rate);
    }
  }
  return std::nullopt;
}

std::pair<double, double> cruise_action(const StepState& ego, const std::vector<StepState>& others,
                                        const std::vector<Vec2>& lane_points, const std::vector<Vec2>& lane_dirs) {
  constexpr double kTargetSpeed = 8.0;
  const Pose frame{ego.x, ego.y, ego.heading};
  const Vec2 centre{ego.x, ego.y};
  std::vector<Vec2> xy;
  for (const StepState& o : others) xy.push_back({o.x, o.y});
  bool ahead = false;
  for (size_t i : nearest(xy, centre, 60.0, 16)) {
    const Vec2 q = to_local(frame, xy[i]);
    ahead = ahead || (q.x > 0 && q.x < 15 && std::abs(q.y) < 2.5);
  }
  const double speed = speed_along(ego);
  const double accel = ahead ? -4.0 : std::clamp(0.5 * (kTargetSpeed - speed), -2.0, 1.5);
  double yaw_rate = 0, best = INFINITY;
  for (size_t i : nearest(lane_points, centre, 40.0, 64)) {
    const Vec2 q = to_local(frame, lane_points[i]);
    const double dir_x = rotate(lane_dirs[i], -ego.heading).x;
    if (q.x > 4 && q.x < 15 && dir_x > 0.7 && std::abs(q.y) < best) {
      best = std::abs(q.y);
      yaw_rate = std::clamp(std::atan2(q.y, q.x), -0.5, 0.5);
    }
  }
  return {accel, yaw_rate};
}

ControlInput advance_pose(int64_t id, const StepState& s, double accel, double yaw_rate) {
  const double dt = kStepSeconds;
  const double v0 = speed_along(s), v1 = std::max(0.0, v0 + accel * dt);
  const double h1 = std::atan2(std::sin(s.heading + yaw_rate * dt), std::cos(s.heading + yaw_rate * dt));
  const double hm = std::atan2(std::sin(s.heading) + std::sin(h1), std::cos(s.heading) + std::cos(h1));
  const double d = 0.5 * (v0 + v1) * dt;
  return {id, s.x + d * std::cos(hm), s.y + d * std::sin(hm), h1, v1};
}

EgoCollision classify_ego_collision(const StepState& ego, const StepState& other) {
  const double ego_depth = point_box_distance(front_point(ego), box_of(other));
  const double other_depth = point_box_distance(front_point(other), box_of(ego));
  // A head-on contact is symmetric in depth: within a centimetre, the faster one strikes.
  const bool ego_strikes = std::abs(ego_depth - other_depth) < 0.01 ? speed_along(ego) >= speed_along(other)
                                                                      : ego_depth < other_depth;
  if (ego_strikes) return EgoCollision::ego_at_fault;
  const bool aligned = std::abs(wrap_angle(other.heading - ego.heading)) <= kPi / 4;
  return aligned ? EgoCollision::rear_end : EgoCollision::side;
}

EgoOutcome ego_outcome(const std::vector<StepResult>& steps, int64_t ego_id, bool ego_off_road) {
  EgoOutcome out;
  out.steps = static_cast<int>(steps.size()) - 1;
  out.off_road = ego_off_road;
  // An overlap counts when it begins between two agents both present at the step before: an agent the log brings in
  // already overlapping another (rule modes add agents as the log has them) did not run into it.
  std::set<int64_t> seen, collided, present_before;
  std::set<std::pair<int64_t, int64_t>> before;  // background pairs overlapping at the previous step
  std::set<int64_t> ego_before;                 // agents overlapping the ego at the previous step
  for (size_t k = 0; k < steps.size(); ++k) {
    const std::vector<AgentView>& agents = steps[k].agents;
    const AgentView* ego = nullptr;
    for (const AgentView& a : agents)
      if (a.id == ego_id) ego = &a;
    std::set<std::pair<int64_t, int64_t>> pairs;
    std::set<int64_t> ego_now;
    for (size_t i = 0; i < agents.size(); ++i) {
      const AgentView& a = agents[i];
      if (a.id == ego_id) continue;
      seen.insert(a.id);
      if (ego && may_touch(ego->state, a.state) && boxes_overlap(box_of(ego->state), box_of(a.state))) {
        ego_now.insert(a.id);
        if (k > 0 && present_before.count(a.id) && !ego_before.count(a.id) && out.collision == EgoCollision::none) {
          out.collision = classify_ego_collision(ego->state, a.state);
          out.collision_step = steps[k].step;
          out.collision_with = a.id;
        }
      }
      for (size_t j = i + 1; j < agents.size(); ++j) {
        const AgentView& b = agents[j];
        if (b.id == ego_id || !may_touch(a.state, b.state) || !boxes_overlap(box_of(a.state), box_of(b.state))) continue;
        const auto key = std::minmax(a.id, b.id);
        pairs.insert(key);
        if (k > 0 && !before.count(key) && present_before.count(a.id) && present_before.count(b.id))
          collided.insert(a.id), collided.insert(b.id);
      }
    }
    before = std::move(pairs);
    ego_before = std::move(ego_now);
    present_before.clear();
    for (const AgentView& a : agents) present_before.insert(a.id);
  }
  out.background_agents = static_cast<int>(seen.size());
  out.background_collided = static_cast<int>(collided.size());
  return out;
}

absl::StatusOr<std::vector<StepResult>> run_ego_episode(std::shared_ptr<const Model> model,
                                                        std::shared_ptr<const Scenario> session_scenario,
                                                        std::shared_ptr<const MapContext> map,
                                                        const SessionOptions& options, const EgoDriver& driver,
                                                        int steps, EgoOutcome* outcome) {
  const Scenario& s = *session_scenario;
  if (s.sdc_track_index < 0) return absl::FailedPreconditionError(absl::StrCat("scenario ", s.id, " names no SDC"));
  const int64_t ego_id = s.tracks[s.sdc_track_index].id;
  SessionOptions o = options;
  o.controlled_ids.clear();
  o.control_sdc = true;
  o.tick_hz = 2;
  auto session = Session::create(std::move(model), session_scenario, std::move(map), o);
  if (!session.ok())
    return absl::Status(session.status().code(), absl::StrCat("scenario ", s.id, ": ", session.status().message()));
  std::vector<StepResult> results = {(*session)->current()};
  const bool ego_controlled = std::any_of(results[0].agents.begin(), results[0].agents.end(),
                                          [&](const AgentView& a) { return a.id == ego_id && a.controlled; });
  if (!ego_controlled)
    return absl::FailedPreconditionError(absl::StrCat("scenario ", s.id, ": the SDC is not a controlled agent"));
  bool off_road = false;
  for (int i = 0; i < steps; ++i) {
    std::vector<ControlInput> controls;
    if (auto c = driver.next(results.back(), (*session)->step_index() + 1)) controls.push_back(*c);
    auto r = (*session)->tick(controls);
    if (!r.ok())
      return absl::Status(r.status().code(), absl::StrCat("scenario ", s.id, " step ", i + 1, ": ", r.status().message()));
    for (const AgentEvents& e : r->events)
      if (e.agent_id == ego_id && e.off_road) off_road = true;
    results.push_back(std::move(*r));
  }
  if (outcome) *outcome = ego_outcome(results, ego_id, off_road && s.tracks[s.sdc_track_index].type == ObjectType::vehicle);
  return results;
}

}  // namespace ss
