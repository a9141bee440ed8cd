// Where full mode puts its own agents, against the log (issue 11's goals for generated scenes): how many agents the
// model places in its region at the first step, and how many of its vehicles stand off the road.
#pragma once

#include <span>

#include "offline/eval/mmd.h"
#include "engine/map/road_edges.h"
#include "engine/scenario/scenario.h"

namespace ss {

// The z of the map point nearest (x, y) in the plane; NaN for a map without points. A linear scan: a few thousand
// points times the agents of one step. Where an agent placed in the plane (the model's) stands.
double ground_z(const Scenario& map, double x, double y);

struct PlacedAgents {
  int agents = 0;            // vehicles, pedestrians and cyclists
  int vehicles = 0;          // of which vehicles, scored for offroad (0 when the map has no road edge)
  int offroad_vehicles = 0;  // vehicles whose most off-road box corner lies beyond the road edge (WOSAC: > 0 m)
  // Every vehicle's speed, whether or not the map scores it for offroad: how many stand (below kStandingSpeed) and
  // the sum of their speeds (for the mean).
  int all_vehicles = 0;
  int standing_vehicles = 0;
  double vehicle_speed_sum = 0;

  PlacedAgents& operator+=(const PlacedAgents& o);
};

inline constexpr double kStandingSpeed = 0.5;  // m/s

double offroad_share(const PlacedAgents& p);   // of the vehicles scored; NaN without any
double standing_share(const PlacedAgents& p);  // of every vehicle; NaN without any
double mean_vehicle_speed(const PlacedAgents& p);

// Counts `agents`, scoring each vehicle's box at its own z, or (NaN z: the model works in the plane) at the z of
// the nearest map point. A map without road edges scores no vehicle.
PlacedAgents placed_agents(std::span<const InitialAgent> agents, std::span<const double> z, const Scenario& map,
                           const RoadEdges& edges);

// The log's side: agents of the model's types valid at the current frame within `radius` of `centre`, the SDC
// included when `with_sdc` (when the model generated a stand-in for it too), at their logged z.
PlacedAgents log_placed_agents(const Scenario& s, const RoadEdges& edges, Vec2 centre, double radius, bool with_sdc);

}  // namespace ss
