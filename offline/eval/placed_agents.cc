#include "offline/eval/placed_agents.h"

#include <cmath>
#include <limits>
#include <vector>

#include "offline/eval/features/map_features.h"
#include "offline/eval/joint_scene.h"
#include "engine/tokens/fidelity.h"

namespace ss {

double ground_z(const Scenario& map, double x, double y) {
  double best = INFINITY, z = std::numeric_limits<double>::quiet_NaN();
  for (const MapFeature& f : map.map_features)
    for (const MapPoint& p : f.points) {
      const double d = (p.x - x) * (p.x - x) + (p.y - y) * (p.y - y);
      if (d < best) best = d, z = p.z;
    }
  return z;
}


PlacedAgents& PlacedAgents::operator+=(const PlacedAgents& o) {
  agents += o.agents, vehicles += o.vehicles, offroad_vehicles += o.offroad_vehicles;
  all_vehicles += o.all_vehicles, standing_vehicles += o.standing_vehicles, vehicle_speed_sum += o.vehicle_speed_sum;
  return *this;
}

double offroad_share(const PlacedAgents& p) {
  return p.vehicles ? static_cast<double>(p.offroad_vehicles) / p.vehicles : std::numeric_limits<double>::quiet_NaN();
}
double standing_share(const PlacedAgents& p) {
  return p.all_vehicles ? static_cast<double>(p.standing_vehicles) / p.all_vehicles
                        : std::numeric_limits<double>::quiet_NaN();
}
double mean_vehicle_speed(const PlacedAgents& p) {
  return p.all_vehicles ? p.vehicle_speed_sum / p.all_vehicles : std::numeric_limits<double>::quiet_NaN();
}

PlacedAgents placed_agents(std::span<const InitialAgent> agents, std::span<const double> z, const Scenario& map,
                           const RoadEdges& edges) {
  PlacedAgents out;
  std::vector<SceneObject> vehicles;
  for (size_t i = 0; i < agents.size(); ++i) {
    const InitialAgent& a = agents[i];
    ++out.agents;
    if (a.type != ObjectType::vehicle) continue;
    const double speed = std::hypot(a.vx, a.vy);
    ++out.all_vehicles;
    out.standing_vehicles += speed < kStandingSpeed;
    out.vehicle_speed_sum += speed;
    if (edges.empty()) continue;
    // The box's bottom is what the feature measures (centre z minus half the height): a zero height puts the bottom
    // at the ground z for agents the model placed in the plane.
    const bool has_z = i < z.size() && std::isfinite(z[i]);
    BoxState b{a.x, a.y, has_z ? z[i] : ground_z(map, a.x, a.y), a.heading, a.length, a.width, 0.0, true};
    vehicles.push_back({0, ObjectType::vehicle, {b}});
  }
  std::vector<int> all(vehicles.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  for (const std::vector<double>& d : distance_to_road_edge(vehicles, all, edges)) {
    if (!std::isfinite(d[0])) continue;
    ++out.vehicles;
    out.offroad_vehicles += d[0] > 0;
  }
  return out;
}

PlacedAgents log_placed_agents(const Scenario& s, const RoadEdges& edges, Vec2 centre, double radius, bool with_sdc) {
  std::vector<InitialAgent> agents;
  std::vector<double> z;
  const int now = s.current_time_index;
  for (size_t i = 0; i < s.tracks.size(); ++i) {
    const Track& t = s.tracks[i];
    if (model_type(t.type) < 0 || now >= static_cast<int>(t.states.size()) || !t.states[now].valid) continue;
    if (static_cast<int>(i) == s.sdc_track_index && !with_sdc) continue;
    const ObjectState& o = t.states[now];
    if (std::hypot(o.x - centre.x, o.y - centre.y) > radius) continue;
    agents.push_back({o.x, o.y, o.heading, o.length, o.width, o.vx, o.vy, t.type});
    z.push_back(o.z - o.height / 2);  // the box's bottom, as placed_agents measures it with a zero height
  }
  return placed_agents(agents, z, s, edges);
}

}  // namespace ss
