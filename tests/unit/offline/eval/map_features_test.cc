// Road-edge distance and traffic-light violations (metrics-spec.md A5, A6): hand-computed cases, the quirks of A9,
// and the official synthetic red-light test on the real WOMD test scenario.
#include "offline/eval/features/map_features.h"

#include <gtest/gtest.h>

#include <cmath>

#include "offline/eval/features/interactive.h"
#include "engine/scenario/read.h"

namespace ss {
namespace {

std::vector<MapPoint> line(std::vector<std::array<double, 2>> xy, double z = 0) {
  std::vector<MapPoint> p;
  for (auto [x, y] : xy) p.push_back({x, y, z});
  return p;
}

TEST(RoadEdge, StraightEdgeSign) {
  // The road lies on the left of the edge's direction.
  const RoadEdges edges({line({{0, 0}, {10, 0}})});
  EXPECT_NEAR(edges.signed_distance(5, -2, 0), 2.0, 1e-12);   // right: off-road
  EXPECT_NEAR(edges.signed_distance(5, 3, 0), -3.0, 1e-12);   // left: on the road
  EXPECT_NEAR(edges.signed_distance(-3, 4, 0), -5.0, 1e-12);  // before the start: the segment's own side
}

TEST(RoadEdge, ConvexTipUsesNeighbourSign) {
  // A hairpin turning left (convex): beyond the tip the point is on the left of the first segment's line but
  // outside the road. The two segments are equally near; the first wins and its "after" rule takes the max sign.
  const RoadEdges edges({line({{0, 0}, {10, 0}, {0, 1}})});
  EXPECT_NEAR(edges.signed_distance(12, 0.5, 0), std::hypot(2.0, 0.5), 1e-12);
}

TEST(RoadEdge, CyclicWrapOnlyForLongestPolyline) {
  // A closed thin triangle whose sharp tip is its first point; the point lies beyond the tip. Wrapping to the last
  // segment gives off-road; without the wrap the first segment's own (wrong) sign is used.
  const auto loop = line({{0, 0}, {10, -1}, {10, 1}, {0, 0}});
  const double d = std::hypot(2.0, 0.5);
  EXPECT_NEAR(RoadEdges({loop}).signed_distance(-2, 0.5, 0), d, 1e-12);
  // With a longer polyline elsewhere the loop no longer wraps (metrics-spec.md A9.4).
  const auto longer = line({{100, 100}, {110, 100}, {120, 100}, {130, 100}, {140, 100}});
  EXPECT_NEAR(RoadEdges({loop, longer}).signed_distance(-2, 0.5, 0), -d, 1e-12);
}

TEST(RoadEdge, HeightChoosesTheLevel) {
  // A road edge at ground level and an overpass edge 10 m up, running the other way.
  const RoadEdges edges({line({{0, 0}, {10, 0}}, 0), line({{10, 3}, {0, 3}}, 10)});
  EXPECT_NEAR(edges.signed_distance(5, 2, 0), -2.0, 1e-12);   // ground: the ground edge, 2 m away
  EXPECT_NEAR(edges.signed_distance(5, 2, 10), -1.0, 1e-12);  // up: the overpass edge, 1 m away
}

TEST(RoadEdge, ZeroLengthSegmentIsNeverOffroad) {
  const RoadEdges edges({line({{0, 0}, {0, 0}})});
  EXPECT_DOUBLE_EQ(edges.signed_distance(3, 4, 0), 0.0);  // metrics-spec.md A9.5
}

TEST(RoadEdge, GridAgreesWithFullScan) {
  // Many polylines: the grid search must give the value a scan of every segment gives (ties to the first).
  std::vector<std::vector<MapPoint>> polylines;
  for (int k = 0; k < 30; ++k) {
    std::vector<MapPoint> p;
    for (int j = 0; j < 8; ++j)
      p.push_back({k * 13.0 + 5 * std::cos(0.7 * j + k), j * 9.0 + 4 * std::sin(1.3 * k + j), 0.3 * j});
    polylines.push_back(p);
  }
  const RoadEdges edges(polylines);
  for (int q = 0; q < 2000; ++q) {  // inside the grid, on cell borders and far outside it
    const double x = -50 + (q * 37 % 500) + 0.25 * (q % 5), y = -40 + (q * 53 % 160) + 0.5 * (q % 3);
    const double z = (q % 7) * 0.5;
    // The magnitude is the plane distance to the segment nearest in 3-D (first among equals): a brute-force scan.
    double best = INFINITY, value = 0;
    for (const auto& p : polylines)
      for (size_t j = 0; j + 1 < p.size(); ++j) {
        const double qx = x - p[j].x, qy = y - p[j].y, qz = z - p[j].z;
        const double dx = p[j + 1].x - p[j].x, dy = p[j + 1].y - p[j].y, dz = p[j + 1].z - p[j].z;
        const double t = std::clamp((qx * dx + qy * dy) / (dx * dx + dy * dy), 0.0, 1.0);
        const double ex = qx - t * dx, ey = qy - t * dy, ez = qz - t * dz;
        const double d3 = std::sqrt(ex * ex + ey * ey + 9 * ez * ez);
        if (d3 < best) best = d3, value = std::hypot(ex, ey);
      }
    EXPECT_NEAR(std::abs(edges.signed_distance(x, y, z)), value, 1e-9) << x << "," << y;
  }
}

TEST(RoadEdge, BoxUsesMostOffroadBottomCorner) {
  const RoadEdges edges({line({{0, 0}, {10, 0}})});
  SceneObject o{1, ObjectType::vehicle, std::vector<BoxState>(2)};
  o.states[0] = {5, 3, 0, 0, 2, 1, 1.5, true};     // corners at y 2.5 and 3.5
  o.states[1] = {5, 0.2, 0, kPi / 2, 2, 1, 1.5, true};  // turned: corners at y -0.8 .. 1.2
  const std::vector<int> eval = {0};
  const std::vector<SceneObject> objects = {o};
  auto d = distance_to_road_edge(objects, eval, edges);
  EXPECT_NEAR(d[0][0], -2.5, 1e-9);
  EXPECT_NEAR(d[0][1], 0.8, 1e-9);
  std::vector<SceneObject> invalid = {o};
  invalid[0].states[1].valid = false;
  d = distance_to_road_edge(invalid, eval, edges);
  EXPECT_DOUBLE_EQ(d[0][1], -kExtremelyLargeDistance);
  EXPECT_TRUE(std::isnan(distance_to_road_edge(objects, eval, RoadEdges({}))[0][0]));
}

// One vehicle driving along x through frames.
SceneObject driver(std::vector<double> xs, double y = 0) {
  SceneObject o{7, ObjectType::vehicle, {}};
  for (double x : xs) o.states.push_back({x, y, 0, 0, 4, 2, 1.5, true});
  return o;
}

std::vector<std::vector<SignalLaneState>> signal(int frames, int64_t lane, SignalState state, MapPoint stop) {
  std::vector<std::vector<SignalLaneState>> s(frames);
  for (auto& f : s) f.push_back({lane, state, stop, true});
  return s;
}

TEST(TrafficLight, CrossingTheStopLineOnRed) {
  const std::vector<EvalLane> lanes = {{11, line({{0, 0}, {10, 0}, {20, 0}})}, {12, line({{0, 50}, {20, 50}})}};
  const std::vector<SceneObject> objects = {driver({8, 9, 11, 12})};
  const std::vector<int> eval = {0};
  auto v = traffic_light_violation(objects, eval, lanes, signal(4, 11, SignalState::stop, {10, 0, 0}));
  EXPECT_EQ(v[0], (std::vector<uint8_t>{0, 0, 1, 0}));
  v = traffic_light_violation(objects, eval, lanes, signal(4, 11, SignalState::arrow_stop, {10, 0, 0}));
  EXPECT_EQ(v[0], (std::vector<uint8_t>{0, 0, 1, 0}));
  // Green, flashing red, or a red on another lane: no violation.
  for (auto [lane, state] : {std::pair{11, SignalState::go}, std::pair{11, SignalState::flashing_stop},
                             std::pair{12, SignalState::stop}})
    EXPECT_EQ(traffic_light_violation(objects, eval, lanes, signal(4, lane, state, {10, 0, 0}))[0],
              (std::vector<uint8_t>(4, 0)));
  // No signals at all.
  EXPECT_EQ(traffic_light_violation(objects, eval, lanes, {})[0], (std::vector<uint8_t>(4, 0)));
  // An invalid frame does not count.
  std::vector<SceneObject> gone = objects;
  gone[0].states[2].valid = false;
  EXPECT_EQ(traffic_light_violation(gone, eval, lanes, signal(4, 11, SignalState::stop, {10, 0, 0}))[0],
            (std::vector<uint8_t>(4, 0)));
}

TEST(TrafficLight, OfficialSyntheticViolation) {
  // traffic_light_features_test: the SDC, stopped at a red light in the WOMD test scenario, is moved 1 m per frame
  // further towards the light from frame 20 on: it must violate; the other evaluated objects must not.
  auto scenarios = read_scenarios(SS_DATA_DIR "/womd/tfrecord/motion_data_one_scenario.tfrecord");
  ASSERT_TRUE(scenarios.ok()) << scenarios.status();
  const Scenario& s = (*scenarios)[0];
  ASSERT_EQ(s.sdc_track_index, 82);
  std::vector<int> all;
  for (size_t i = 0; i < s.tracks.size(); ++i) all.push_back(static_cast<int>(i));
  JointScene scene = log_scene(s, all);
  // The official test uses the log's sizes at every frame; the crossing test reads centres only.
  for (int f = 20; f < s.num_frames(); ++f) scene.objects[82].states[f].y -= f - 20;
  const std::vector<int> eval = {42, 43, 72, 82};
  const auto v = traffic_light_violation(scene.objects, eval, surface_street_lanes(s), s.signals);
  for (int e = 0; e < 3; ++e)
    for (uint8_t x : v[e]) EXPECT_FALSE(x) << "object " << eval[e];
  bool sdc = false;
  for (uint8_t x : v[3]) sdc = sdc || x;
  EXPECT_TRUE(sdc);
  // The unmodified log has no violation.
  const JointScene log = log_scene(s, all);
  for (const auto& row : traffic_light_violation(log.objects, eval, surface_street_lanes(s), s.signals))
    for (uint8_t x : row) EXPECT_FALSE(x);
}

}  // namespace
}  // namespace ss
