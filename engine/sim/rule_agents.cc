#include "engine/sim/rule_agents.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ss {

double idm_acceleration(const IdmParams& p, double v, double v0, double gap, double v_lead) {
  double free_term;
  if (v0 < p.stopped_speed) {
    // The log stands still here: come to a stop at the comfortable rate (IDM's (v / v0)^delta has no limit at 0).
    free_term = -std::min(p.comfort_brake, v / 0.5);
  } else {
    free_term = p.max_accel * (1 - std::pow(v / v0, p.delta));
  }
  double interaction = 0;
  if (std::isfinite(gap)) {
    if (gap <= 0) return -p.max_brake;
    const double dv = v - v_lead;
    const double desired = p.min_gap + std::max(0.0, v * p.headway + v * dv / (2 * std::sqrt(p.max_accel * p.comfort_brake)));
    interaction = -p.max_accel * (desired / gap) * (desired / gap);
  }
  return std::clamp(free_term + interaction, -p.max_brake, p.max_accel);
}

LoggedPath logged_path(const Track& track) {
  LoggedPath path;
  for (size_t f = 0; f < track.states.size(); ++f) {
    const ObjectState& o = track.states[f];
    if (!o.valid) continue;
    const Vec2 q{o.x, o.y};
    // A standing vehicle logs the same point many times: one point per place keeps every segment's length positive.
    if (!path.points.empty() && distance(q, path.points.back()) < 1e-3) continue;
    path.s.push_back(path.points.empty() ? 0.0 : path.s.back() + distance(q, path.points.back()));
    path.points.push_back(q);
    path.heading.push_back(o.heading);
    path.frame.push_back(static_cast<int>(f));
  }
  return path;
}

Pose path_pose(const LoggedPath& path, double s) {
  const size_t n = path.points.size();
  if (n == 0) return {};
  const auto along = [](Vec2 p, double heading, double d) {
    return Pose{p.x + d * std::cos(heading), p.y + d * std::sin(heading), heading};
  };
  // Headings are the log's, interpolated: a segment's own direction is noise where the logged vehicle creeps (a few
  // centimetres between frames), and a box turned by that noise sweeps the neighbouring lane or the kerb.
  if (s <= 0) return along(path.points[0], path.heading[0], s);
  if (s >= path.s.back()) return along(path.points[n - 1], path.heading[n - 1], s - path.s.back());
  const size_t i = static_cast<size_t>(std::upper_bound(path.s.begin(), path.s.end(), s) - path.s.begin()) - 1;
  const double t = (s - path.s[i]) / (path.s[i + 1] - path.s[i]);
  const Vec2 p = path.points[i] + t * (path.points[i + 1] - path.points[i]);
  return {p.x, p.y, wrap_angle(path.heading[i] + t * wrap_angle(path.heading[i + 1] - path.heading[i]))};
}

double path_s_at_frame(const LoggedPath& path, int frame) {
  const auto it = std::upper_bound(path.frame.begin(), path.frame.end(), frame);
  if (it == path.frame.begin()) return 0.0;
  return path.s[static_cast<size_t>(it - path.frame.begin()) - 1];
}

IdmMove idm_step(const IdmParams& p, const LoggedPath& path, double s, double v, double v0, double length,
                 double width, std::span<const IdmOther> others, double dt) {
  const Pose here = path_pose(path, s);
  std::vector<const IdmOther*> near;
  for (const IdmOther& o : others) {
    const double reach = p.lookahead + length + norm({o.box.length, o.box.width});
    if (distance({here.x, here.y}, {o.box.pose.x, o.box.pose.y}) <= reach) near.push_back(&o);
  }
  double gap = std::numeric_limits<double>::infinity(), v_lead = 0;
  for (double d = p.probe_step; d <= p.lookahead + 1e-9 && !near.empty() && !std::isfinite(gap); d += p.probe_step) {
    const Pose q = path_pose(path, s + d);
    const Box b{q, length, width};
    for (const IdmOther* o : near)
      if (boxes_overlap(b, o->box)) {
        // The box first touches the other between the last position tried and this one: the lower bound.
        gap = d - p.probe_step;
        v_lead = dot(o->velocity, {std::cos(q.heading), std::sin(q.heading)});
        break;
      }
  }
  const double a = idm_acceleration(p, v, v0, gap, v_lead);
  double v1 = v + a * dt, ds;
  if (v1 < 0) {
    ds = a < 0 ? v * v / (-2 * a) : 0.0;  // stops within the step
    v1 = 0;
  } else {
    ds = (v + v1) / 2 * dt;
  }
  return {s + ds, v1, gap};
}

}  // namespace ss
