// Where full mode's agents stand: counts in the region, the offroad share of vehicles and how many of them stand, on
// a hand-made road.
#include "offline/eval/placed_agents.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

// A straight road 10 m wide along x at z = 0: an edge on each side, the road on each edge's left.
Scenario road() {
  Scenario s;
  s.id = "road";
  for (const auto& points :
       {std::vector<MapPoint>{{-100, -5, 0}, {100, -5, 0}}, std::vector<MapPoint>{{100, 5, 0}, {-100, 5, 0}}}) {
    MapFeature edge;
    edge.kind = MapFeatureKind::road_edge;
    edge.points = points;
    s.map_features.push_back(edge);
  }
  return s;
}

Track track(int32_t id, ObjectType type, double x, double y) {
  Track t{id, type, {}};
  ObjectState o;
  o.x = x, o.y = y, o.z = 0.8, o.length = 4, o.width = 2, o.height = 1.6, o.valid = true;
  t.states = {o};
  return t;
}

TEST(PlacedAgents, CountsEveryTypeAndScoresVehiclesOnly) {
  const Scenario s = road();
  const RoadEdges edges = RoadEdges::from_scenario(s);
  const std::vector<InitialAgent> agents = {
      {0, 0, 0, 4, 2, 3, 4, ObjectType::vehicle},            // on the road, at 5 m/s
      {0, 4.5, 0, 4, 2, 0.3, 0, ObjectType::vehicle},        // a corner 0.5 m past the left edge; standing
      {0, 20, 0, 4, 2, 0, 0, ObjectType::vehicle},           // far off the road; standing
      {0, 8, 0, 0.5, 0.5, 1.5, 0, ObjectType::pedestrian}};  // off the road, as pedestrians are: not scored
  // No z given: the model's agents stand at the ground (the nearest map point's z).
  const PlacedAgents p = placed_agents(agents, {}, s, edges);
  EXPECT_EQ(p.agents, 4);
  EXPECT_EQ(p.vehicles, 3);
  EXPECT_EQ(p.offroad_vehicles, 2);
  EXPECT_DOUBLE_EQ(offroad_share(p), 2.0 / 3);
  // Speeds: vehicles only, below kStandingSpeed standing.
  EXPECT_EQ(p.all_vehicles, 3);
  EXPECT_EQ(p.standing_vehicles, 2);
  EXPECT_DOUBLE_EQ(standing_share(p), 2.0 / 3);
  EXPECT_DOUBLE_EQ(mean_vehicle_speed(p), 5.3 / 3);
  // Summed over rollouts, every count and the speed sum add up.
  PlacedAgents sum = p;
  sum += p;
  EXPECT_EQ(sum.agents, 8);
  EXPECT_EQ(sum.offroad_vehicles, 4);
  EXPECT_EQ(sum.standing_vehicles, 4);
  EXPECT_DOUBLE_EQ(mean_vehicle_speed(sum), 5.3 / 3);
  EXPECT_TRUE(std::isnan(standing_share(PlacedAgents{})));
}

TEST(PlacedAgents, NoRoadEdgeScoresNoVehicle) {
  Scenario s = road();
  s.map_features.clear();
  const PlacedAgents p = placed_agents(std::vector<InitialAgent>{{0, 20, 0, 4, 2, 0, 0, ObjectType::vehicle}}, {}, s,
                                       RoadEdges::from_scenario(s));
  EXPECT_EQ(p.agents, 1);
  EXPECT_EQ(p.vehicles, 0);
  EXPECT_EQ(p.offroad_vehicles, 0);
  EXPECT_TRUE(std::isnan(offroad_share(p)));
  EXPECT_EQ(p.all_vehicles, 1);  // its speed still counts
}

TEST(PlacedAgents, LogSideKeepsTheRegionAndTheSdcRule) {
  Scenario s = road();
  s.timestamps = {0.0};
  s.current_time_index = 0;
  s.tracks = {track(1, ObjectType::vehicle, 0, 0),        // the SDC
              track(2, ObjectType::vehicle, 30, 7),       // inside the region, off the road
              track(3, ObjectType::cyclist, 50, 0),       // inside
              track(4, ObjectType::vehicle, 150, 0),      // outside the 100 m region
              track(5, ObjectType::other, 10, 0)};        // a type the model does not make
  s.sdc_track_index = 0;
  const RoadEdges edges = RoadEdges::from_scenario(s);
  const PlacedAgents with_sdc = log_placed_agents(s, edges, {0, 0}, 100, true);
  EXPECT_EQ(with_sdc.agents, 3);
  EXPECT_EQ(with_sdc.vehicles, 2);
  EXPECT_EQ(with_sdc.offroad_vehicles, 1);
  const PlacedAgents without = log_placed_agents(s, edges, {0, 0}, 100, false);
  EXPECT_EQ(without.agents, 2);
  EXPECT_EQ(without.vehicles, 1);
  EXPECT_EQ(without.offroad_vehicles, 1);
}

}  // namespace
}  // namespace ss
