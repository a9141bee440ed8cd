#include "engine/sim/events.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace ss {
namespace {


}  // namespace

EventMap event_map_from_scenario(const Scenario& scenario) {
  EventMap m;
  std::vector<std::vector<MapPoint>> edges;
  for (const MapFeature& f : scenario.map_features) {
    if (f.kind == MapFeatureKind::road_edge) {
      std::vector<MapPoint> flat;
      for (const MapPoint& p : f.points) flat.push_back({p.x, p.y, 0});
      edges.push_back(std::move(flat));
    }
    if (f.kind != MapFeatureKind::lane || f.points.size() < 2) continue;
    EventMap::Lane lane;
    lane.id = f.id;
    lane.lo = {INFINITY, INFINITY};
    lane.hi = {-INFINITY, -INFINITY};
    for (const MapPoint& p : f.points) {
      const Vec2 q{p.x, p.y};
      lane.s.push_back(lane.points.empty() ? 0.0 : lane.s.back() + distance(lane.points.back(), q));
      lane.points.push_back(q);
      lane.lo = {std::min(lane.lo.x, q.x), std::min(lane.lo.y, q.y)};
      lane.hi = {std::max(lane.hi.x, q.x), std::max(lane.hi.y, q.y)};
    }
    m.lanes.push_back(std::move(lane));
  }
  m.edges = RoadEdges(std::move(edges));
  return m;
}

size_t EventMap::bytes() const {
  size_t b = sizeof(*this) + edges.bytes() + lanes.capacity() * sizeof(Lane);
  for (const Lane& l : lanes) b += l.points.capacity() * sizeof(Vec2) + l.s.capacity() * sizeof(double);
  return b;
}

LanePosition lane_position(const EventMap& map, const Pose& pose) {
  LanePosition best;
  double best_d = kLaneMaxDistance;
  const Vec2 p{pose.x, pose.y};
  for (const EventMap::Lane& lane : map.lanes) {
    if (p.x < lane.lo.x - best_d || p.x > lane.hi.x + best_d || p.y < lane.lo.y - best_d || p.y > lane.hi.y + best_d)
      continue;
    for (size_t j = 0; j + 1 < lane.points.size(); ++j) {
      const Vec2 a = lane.points[j], d = lane.points[j + 1] - a;
      const double len = norm(d);
      if (len <= 0) continue;
      const Vec2 u = (1.0 / len) * d;
      const double heading_error = wrap_angle(pose.heading - std::atan2(u.y, u.x));
      if (std::abs(heading_error) >= kPi / 2) continue;
      const double t = std::clamp(dot(p - a, u), 0.0, len);
      const double dist = distance(p, a + t * u);
      // Strictly nearer wins: among equals (two lanes sharing a point) the first in map order keeps it.
      if (dist < best_d) {
        best_d = dist;
        best.lane_id = lane.id;
        best.s = lane.s[j] + t;
        best.offset = cross(u, p - a);
        best.heading_error = heading_error;
        best.direction = u;
      }
    }
  }
  return best;
}

std::vector<AgentEvents> tick_events(const EventMap& map, const StepResult& before, const StepResult& after) {
  std::map<int64_t, const AgentView*> previous;
  for (const AgentView& a : before.agents) previous[a.id] = &a;
  std::vector<AgentEvents> out;
  for (const AgentView& a : after.agents) {
    if (!a.controlled) continue;
    AgentEvents e;
    e.agent_id = a.id;
    const Box box = box_of(a.state);
    for (const AgentView& o : after.agents)
      if (o.id != a.id && boxes_overlap(box, box_of(o.state))) e.overlapping.push_back(o.id);
    std::sort(e.overlapping.begin(), e.overlapping.end());

    if (map.edges.empty()) {
      e.road_edge_distance = std::numeric_limits<double>::quiet_NaN();
    } else {
      e.road_edge_distance = -INFINITY;
      for (const Vec2& c : box_corners(box))
        e.road_edge_distance = std::max(e.road_edge_distance, map.edges.signed_distance(c.x, c.y, 0));
      e.off_road = e.road_edge_distance > 0;
    }

    const Pose pose{a.state.x, a.state.y, a.state.heading};
    e.lane = lane_position(map, pose);
    auto it = previous.find(a.id);
    if (it != previous.end()) {
      const StepState& b = it->second->state;
      const Vec2 p0{b.x, b.y}, p1{a.state.x, a.state.y};
      Vec2 dir = e.lane.direction;
      if (e.lane.lane_id < 0) {
        const LanePosition old = lane_position(map, {b.x, b.y, b.heading});
        dir = old.lane_id < 0 ? Vec2{0, 0} : old.direction;
      }
      e.progress = dot(p1 - p0, dir);
      for (const LightView& l : after.lights) {
        if (l.state != LightState::red) continue;
        const Vec2 stop{l.stop_point.x, l.stop_point.y};
        const Vec2 u{std::cos(l.stop_point.heading), std::sin(l.stop_point.heading)};
        const double a0 = dot(p0 - stop, u), a1 = dot(p1 - stop, u);
        if (!(a0 < 0 && a1 >= 0)) continue;
        const Vec2 at = p0 + (-a0 / (a1 - a0)) * (p1 - p0);  // where the centre's path meets the line
        if (std::abs(cross(u, at - stop)) > kStopLineHalfWidth) continue;
        e.ran_red_light = true;
        e.red_light_lane = l.lane;
        break;
      }
    }
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace ss
