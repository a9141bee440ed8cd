#include "engine/map/segments.h"

#include <cmath>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "engine/scenario/read.h"

namespace ss {
namespace {

MapFeature polyline(MapFeatureKind kind, std::vector<MapPoint> points, int32_t subtype = 0, int64_t id = 1) {
  MapFeature f;
  f.id = id;
  f.kind = kind;
  f.subtype = subtype;
  f.points = std::move(points);
  return f;
}

Scenario scenario_of(std::vector<MapFeature> features) {
  Scenario s;
  s.map_features = std::move(features);
  return s;
}

// A straight lane along x from the origin with `n` points `spacing` apart.
MapFeature straight_lane(int n, double spacing) {
  std::vector<MapPoint> pts;
  for (int i = 0; i < n; ++i) pts.push_back({i * spacing, 0, 0});
  return polyline(MapFeatureKind::lane, pts);
}

TEST(SegmentMap, StraightLaneIsCutEveryTenMetresSharingEndpoints) {
  auto segs = segment_map(scenario_of({straight_lane(51, 0.5)}));  // 25 m, 50 vectors
  ASSERT_EQ(segs.size(), 3u);
  const int vectors[] = {20, 20, 10};
  const double lengths[] = {10, 10, 5};
  const int firsts[] = {0, 20, 40};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(segs[i].num_vectors(), vectors[i]);
    EXPECT_DOUBLE_EQ(segs[i].length, lengths[i]);
    EXPECT_EQ(segs[i].first_point, firsts[i]);
    EXPECT_EQ(segs[i].points.front().x, firsts[i] * 0.5);
    EXPECT_EQ(segs[i].feature_index, 0);
    EXPECT_EQ(segs[i].kind, MapFeatureKind::lane);
    EXPECT_DOUBLE_EQ(segs[i].pose.heading, 0);
    EXPECT_DOUBLE_EQ(segs[i].pose.y, 0);
  }
  EXPECT_EQ(segs[0].points.back(), segs[1].points.front());
  EXPECT_EQ(segs[1].points.back(), segs[2].points.front());
  EXPECT_EQ(segs[2].points.back().x, 25.0);
  // Mean of vector midpoints: the middle of each piece of a straight evenly spaced line.
  EXPECT_DOUBLE_EQ(segs[0].pose.x, 5);
  EXPECT_DOUBLE_EQ(segs[1].pose.x, 15);
  EXPECT_DOUBLE_EQ(segs[2].pose.x, 22.5);
}

TEST(SegmentMap, DenseLaneIsCutAtThirtyVectors) {
  auto segs = segment_map(scenario_of({straight_lane(40, 0.1)}));  // 39 vectors, 3.9 m
  ASSERT_EQ(segs.size(), 2u);
  EXPECT_EQ(segs[0].num_vectors(), 30);
  EXPECT_EQ(segs[1].num_vectors(), 9);
  EXPECT_EQ(segs[1].first_point, 30);
  EXPECT_NEAR(segs[0].length, 3.0, 1e-12);
  EXPECT_NEAR(segs[1].length, 0.9, 1e-12);
  EXPECT_EQ(segs[0].points.back(), segs[1].points.front());
}

TEST(SegmentMap, ExactlyThirtyVectorsIsOneSegment) {
  auto segs = segment_map(scenario_of({straight_lane(31, 0.1)}));
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_EQ(segs[0].num_vectors(), 30);
}

TEST(SegmentMap, CrosswalkIsOneClosedSegment) {
  // 20 m x 4 m: the long sides alone exceed 10 m, but crosswalks are never cut by length.
  auto f = polyline(MapFeatureKind::crosswalk, {{0, 0, 0}, {20, 0, 0}, {20, 4, 0}, {0, 4, 0}});
  auto segs = segment_map(scenario_of({f}));
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_EQ(segs[0].num_vectors(), 4);
  EXPECT_EQ(segs[0].points.front(), segs[0].points.back());
  EXPECT_DOUBLE_EQ(segs[0].length, 48);
  EXPECT_DOUBLE_EQ(segs[0].pose.x, 10);
  EXPECT_DOUBLE_EQ(segs[0].pose.y, 2);
  EXPECT_EQ(segs[0].flags[kFlagCrosswalk], 1);
}

TEST(SegmentMap, CrosswalkIsCutAtThirtyVectors) {
  std::vector<MapPoint> ring;
  for (int i = 0; i < 40; ++i) ring.push_back({std::cos(2 * kPi * i / 40), std::sin(2 * kPi * i / 40), 0});
  auto segs = segment_map(scenario_of({polyline(MapFeatureKind::crosswalk, ring)}));
  ASSERT_EQ(segs.size(), 2u);
  EXPECT_EQ(segs[0].num_vectors(), 30);
  EXPECT_EQ(segs[1].num_vectors(), 10);  // 40 vectors once closed
  EXPECT_EQ(segs[1].points.back(), ring.front());
}

TEST(SegmentMap, OtherPolygonsAreClosedThenCutByLength) {
  // Vectors once closed: 20, 4, 20, 4 m -> cut after 20 | 4 + 20 | 4.
  auto f = polyline(MapFeatureKind::speed_bump, {{0, 0, 0}, {20, 0, 0}, {20, 4, 0}, {0, 4, 0}});
  auto segs = segment_map(scenario_of({f}));
  ASSERT_EQ(segs.size(), 3u);
  EXPECT_EQ(segs[0].num_vectors(), 1);
  EXPECT_EQ(segs[1].num_vectors(), 2);
  EXPECT_EQ(segs[2].num_vectors(), 1);
  EXPECT_EQ(segs[2].first_point, 3);
  EXPECT_EQ(segs[2].points.back(), f.points.front());
  EXPECT_EQ(segs[0].flags[kFlagSpeedBump], 1);

  auto d = polyline(MapFeatureKind::driveway, {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}});
  auto dsegs = segment_map(scenario_of({d}));
  ASSERT_EQ(dsegs.size(), 1u);
  EXPECT_EQ(dsegs[0].num_vectors(), 3);
  EXPECT_EQ(dsegs[0].flags[kFlagDriveway], 1);
}

TEST(SegmentMap, PolygonThatRepeatsItsFirstPointIsNotClosedTwice) {
  auto f = polyline(MapFeatureKind::crosswalk, {{0, 0, 0}, {4, 0, 0}, {4, 4, 0}, {0, 0, 0}});
  auto segs = segment_map(scenario_of({f}));
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_EQ(segs[0].num_vectors(), 3);
}

TEST(SegmentMap, FeaturesWithFewerThanTwoPointsYieldNothing) {
  auto one = polyline(MapFeatureKind::lane, {{1, 2, 3}});
  auto none = polyline(MapFeatureKind::road_edge, {});
  auto two = polyline(MapFeatureKind::road_edge, {{0, 0, 0}, {1, 0, 0}});
  auto segs = segment_map(scenario_of({one, none, two}));
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_EQ(segs[0].feature_index, 2);
  EXPECT_EQ(segs[0].flags[kFlagRoadBoundaryLine], 1);
}

TEST(SegmentMap, PoseIsMeanOfMidpointsAndCircularMeanAcrossTheWrap) {
  // Two vectors heading pi - 0.1 and -pi + 0.1: the plain mean would be 0, the circular mean is pi.
  double c = std::cos(0.1), s = std::sin(0.1);
  auto f = polyline(MapFeatureKind::lane, {{0, 0, 1}, {-c, s, 2}, {-2 * c, 0, 3}});
  auto segs = segment_map(scenario_of({f}));
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_NEAR(std::abs(wrap_angle(segs[0].pose.heading - kPi)), 0, 1e-12);
  EXPECT_DOUBLE_EQ(segs[0].pose.x, -c);
  EXPECT_DOUBLE_EQ(segs[0].pose.y, s / 2);
  EXPECT_DOUBLE_EQ(segs[0].z, 2);
}

TEST(SegmentMap, ZeroLengthVectorsDoNotVoteOnHeading) {
  auto f = polyline(MapFeatureKind::lane, {{0, 0, 0}, {1, 1, 0}, {1, 1, 0}});
  auto segs = segment_map(scenario_of({f}));
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_EQ(segs[0].num_vectors(), 2);  // the repeated point is still a vector
  EXPECT_DOUBLE_EQ(segs[0].pose.heading, kPi / 4);
  EXPECT_DOUBLE_EQ(segs[0].pose.x, 0.75);

  auto still = polyline(MapFeatureKind::lane, {{2, 3, 0}, {2, 3, 0}});
  auto ssegs = segment_map(scenario_of({still}));
  ASSERT_EQ(ssegs.size(), 1u);
  EXPECT_EQ(ssegs[0].pose.heading, 0);
  EXPECT_EQ(ssegs[0].length, 0);
}

TEST(SegmentMap, StopSignHeadsAlongTheNearestVectorOfItsFirstLane) {
  MapFeature sign;
  sign.id = 7;
  sign.kind = MapFeatureKind::stop_sign;
  sign.points = {{5, 9, 1}};
  sign.stop_sign_lanes = {42, 43};
  // Lane 42 runs east then turns north; the sign is beside the northbound part. Lane 43 runs west.
  auto lane42 = polyline(MapFeatureKind::lane, {{0, 0, 0}, {4, 0, 0}, {4, 10, 0}}, 2, 42);
  auto lane43 = polyline(MapFeatureKind::lane, {{10, 9, 0}, {0, 9, 0}}, 2, 43);
  // The sign comes first: its lane is looked up across the whole map.
  auto segs = segment_map(scenario_of({sign, lane42, lane43}));
  ASSERT_EQ(segs.size(), 3u);
  const MapSegment& s = segs[0];
  EXPECT_EQ(s.kind, MapFeatureKind::stop_sign);
  EXPECT_EQ(s.feature_id, 7);
  EXPECT_EQ(s.num_vectors(), 1);
  EXPECT_EQ(s.points[0], s.points[1]);
  EXPECT_DOUBLE_EQ(s.pose.x, 5);
  EXPECT_DOUBLE_EQ(s.pose.y, 9);
  EXPECT_DOUBLE_EQ(s.z, 1);
  EXPECT_EQ(s.length, 0);
  EXPECT_DOUBLE_EQ(s.pose.heading, kPi / 2);
  EXPECT_EQ(s.flags[kFlagStopSign], 1);

  sign.stop_sign_lanes = {99};  // unknown lane
  EXPECT_EQ(segment_map(scenario_of({sign, lane42}))[0].pose.heading, 0);
  sign.stop_sign_lanes.clear();
  EXPECT_EQ(segment_map(scenario_of({sign, lane42}))[0].pose.heading, 0);
  sign.points.clear();
  EXPECT_EQ(segment_map(scenario_of({sign})).size(), 0u);
}

TEST(SegmentMap, TypeFlags) {
  using F = std::array<int, kNumMapTypeFlags>;
  auto flags_of = [](MapFeatureKind kind, int32_t subtype) {
    auto segs = segment_map(scenario_of({polyline(kind, {{0, 0, 0}, {1, 0, 0}}, subtype)}));
    F out{};
    for (int i = 0; i < kNumMapTypeFlags; ++i) out[i] = static_cast<int>(segs.at(0).flags[i]);
    return out;
  };
  //             lane sdwk edge line brkn sold yell whit drvw xwlk bump stop
  EXPECT_EQ(flags_of(MapFeatureKind::lane, 2), (F{1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(flags_of(MapFeatureKind::road_edge, 1), (F{0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0}));
  const struct {
    RoadLineType type;
    F flags;
  } lines[] = {
      {RoadLineType::unknown, {0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0}},
      {RoadLineType::broken_single_white, {0, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 0}},
      {RoadLineType::solid_single_white, {0, 0, 0, 1, 0, 1, 0, 1, 0, 0, 0, 0}},
      {RoadLineType::solid_double_white, {0, 0, 0, 1, 0, 1, 0, 1, 0, 0, 0, 0}},
      {RoadLineType::broken_single_yellow, {0, 0, 0, 1, 1, 0, 1, 0, 0, 0, 0, 0}},
      {RoadLineType::broken_double_yellow, {0, 0, 0, 1, 1, 0, 1, 0, 0, 0, 0, 0}},
      {RoadLineType::solid_single_yellow, {0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 0, 0}},
      {RoadLineType::solid_double_yellow, {0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 0, 0}},
      {RoadLineType::passing_double_yellow, {0, 0, 0, 1, 1, 1, 1, 0, 0, 0, 0, 0}},
  };
  for (const auto& l : lines)
    EXPECT_EQ(flags_of(MapFeatureKind::road_line, static_cast<int32_t>(l.type)), l.flags)
        << "road line type " << static_cast<int>(l.type);
  EXPECT_EQ(flags_of(MapFeatureKind::crosswalk, 0), (F{0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0}));
  EXPECT_EQ(flags_of(MapFeatureKind::speed_bump, 0), (F{0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0}));
  EXPECT_EQ(flags_of(MapFeatureKind::driveway, 0), (F{0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0}));
}

TEST(SegmentPointFeatures, ValuesInTheSegmentFrame) {
  MapSegment s;
  s.pose = {10, 20, kPi / 2};  // x of the frame points north
  s.z = 1;
  s.length = 7;
  s.points = {{10, 19, 0.5}, {10, 21, 1.5}, {9, 21, 1.5}};
  s.flags[kFlagRoadLine] = 1;
  s.flags[kFlagSolidLine] = 1;
  s.flags[kFlagYellowLine] = 1;
  auto f = segment_point_features(s);
  auto at = [&](int row, int col) { return f[row * kPointFeatureDim + col]; };
  const float r5 = std::sqrt(5.0f);
  // Vector 0 runs north: along the frame's x.
  const float row0[13] = {-1, 0, -0.5f, 1, 0, 0.5f, 2, 0, 1, 0, 0, 1, r5};
  // Vector 1 runs west: the frame's +y, heading +pi/2 relative to the segment.
  const float row1[13] = {1, 0, 0.5f, 1, 1, 0.5f, 0, 1, 0, static_cast<float>(kPi / 2), 1, 0, 1};
  for (int k = 0; k < 13; ++k) {
    EXPECT_NEAR(at(0, k), row0[k], 1e-6) << "row 0 col " << k;
    EXPECT_NEAR(at(1, k), row1[k], 1e-6) << "row 1 col " << k;
  }
  for (int row = 0; row < 2; ++row) {
    for (int k = 0; k < kNumMapTypeFlags; ++k) EXPECT_EQ(at(row, 13 + k), s.flags[k]);
    EXPECT_EQ(at(row, 25), 7);
    EXPECT_EQ(at(row, 26), 1);
  }
  for (int row = 2; row < kMaxVectorsPerSegment; ++row)
    for (int k = 0; k < kPointFeatureDim; ++k) EXPECT_EQ(at(row, k), 0) << row << " " << k;
}

TEST(SegmentPointFeatures, HeadingIsWrappedRelativeToTheSegment) {
  MapSegment s;
  s.pose = {0, 0, 3.0};
  s.points = {{0, 0, 0}, {std::cos(-3.0), std::sin(-3.0), 0}};
  auto f = segment_point_features(s);
  double expected = wrap_angle(-6.0);  // 0.283...
  EXPECT_NEAR(f[9], expected, 1e-6);
  EXPECT_NEAR(f[10], std::sin(expected), 1e-6);
  EXPECT_NEAR(f[11], std::cos(expected), 1e-6);
}

TEST(SegmentPointFeatures, StopSignRow) {
  MapFeature sign;
  sign.kind = MapFeatureKind::stop_sign;
  sign.points = {{3000.5, -1200.25, 7}};
  auto segs = segment_map(scenario_of({sign}));
  ASSERT_EQ(segs.size(), 1u);
  auto f = segment_point_features(segs[0]);
  for (int k = 0; k < 9; ++k) EXPECT_EQ(f[k], 0) << k;
  EXPECT_EQ(f[9], 0);   // heading relative to the segment
  EXPECT_EQ(f[10], 0);  // sin
  EXPECT_EQ(f[11], 1);  // cos
  EXPECT_EQ(f[12], 0);  // vector length
  EXPECT_EQ(f[13 + kFlagStopSign], 1);
  EXPECT_EQ(f[25], 0);
  EXPECT_EQ(f[26], 1);
  EXPECT_EQ(f[kPointFeatureDim + 26], 0);
}

TEST(SegmentPointFeatures, LargeCoordinatesKeepCentimetres) {
  std::vector<MapPoint> pts;
  for (int i = 0; i < 5; ++i) pts.push_back({8000.0 + 0.01 * i, -6000.0, 0});
  auto segs = segment_map(scenario_of({polyline(MapFeatureKind::lane, pts)}));
  auto f = segment_point_features(segs.at(0));
  EXPECT_NEAR(f[0], -0.02, 1e-6);
  EXPECT_NEAR(f[3], -0.01, 1e-6);
  EXPECT_NEAR(f[12], 0.01, 1e-6);
}

MapSegment at(double x, double y, int feature_index) {
  MapSegment s;
  s.pose = {x, y, 0};
  s.feature_index = feature_index;
  return s;
}

TEST(NearestSegments, NearestFirstTiesInOriginalOrderAndCapped) {
  std::vector<MapSegment> segs = {at(3, 0, 0), at(0, 1, 1), at(2, 0, 2), at(-1, 0, 3), at(0, -5, 4)};
  auto order = [](const std::vector<MapSegment>& v) {
    std::vector<int> out;
    for (const auto& s : v) out.push_back(s.feature_index);
    return out;
  };
  EXPECT_EQ(order(nearest_segments(segs, {0, 0})), (std::vector<int>{1, 3, 2, 0, 4}));
  EXPECT_EQ(order(nearest_segments(segs, {0, 0}, 2)), (std::vector<int>{1, 3}));
  EXPECT_EQ(order(nearest_segments(segs, {3, 0}, 1)), (std::vector<int>{0}));
  EXPECT_TRUE(nearest_segments(segs, {0, 0}, 0).empty());
  EXPECT_TRUE(nearest_segments({}, {0, 0}).empty());
}

// The real WOMD map: structural invariants of every segment.
TEST(SegmentMapReal, WomdScenarioInvariants) {
  auto scenarios = read_scenarios(std::string(SS_DATA_DIR) + "/womd/tfrecord/motion_data_one_scenario.tfrecord");
  ASSERT_TRUE(scenarios.ok()) << scenarios.status();
  ASSERT_EQ(scenarios->size(), 1u);
  const Scenario& sc = scenarios->front();
  ASSERT_EQ(sc.map_features.size(), 301u);
  auto segs = segment_map(sc);
  ASSERT_GT(segs.size(), 301u);
  std::vector<int> vectors_per_feature(sc.map_features.size(), 0);
  for (size_t i = 0; i < segs.size(); ++i) {
    const MapSegment& s = segs[i];
    SCOPED_TRACE("segment " + std::to_string(i));
    ASSERT_GE(s.num_vectors(), 1);
    EXPECT_LE(s.num_vectors(), kMaxVectorsPerSegment);
    if (i > 0) {
      EXPECT_GE(s.feature_index, segs[i - 1].feature_index);
    }
    const MapFeature& f = sc.map_features[s.feature_index];
    EXPECT_EQ(s.feature_id, f.id);
    EXPECT_EQ(s.points.front(), f.points[s.first_point]);
    if (s.kind != MapFeatureKind::crosswalk) {
      const MapPoint& a = s.points[s.points.size() - 2];
      const MapPoint& b = s.points.back();
      double last = std::sqrt((b.x - a.x) * (b.x - a.x) + (b.y - a.y) * (b.y - a.y) + (b.z - a.z) * (b.z - a.z));
      EXPECT_LE(s.length, kMaxSegmentLength + last + 1e-9);
    }
    // Consecutive segments of one feature share the boundary point.
    if (i > 0 && segs[i - 1].feature_index == s.feature_index) {
      EXPECT_EQ(segs[i - 1].points.back(), s.points.front());
    }
    vectors_per_feature[s.feature_index] += s.num_vectors();
    EXPECT_TRUE(std::isfinite(s.pose.x) && std::isfinite(s.pose.y) && std::isfinite(s.pose.heading));
    auto feats = segment_point_features(s);
    for (float v : feats) ASSERT_TRUE(std::isfinite(v));
    for (int r = 0; r < kMaxVectorsPerSegment; ++r)
      EXPECT_EQ(feats[r * kPointFeatureDim + 26], r < s.num_vectors() ? 1 : 0);
  }
  // No vector is lost or duplicated: polylines keep n - 1 vectors, closed polygons n.
  for (size_t fi = 0; fi < sc.map_features.size(); ++fi) {
    const MapFeature& f = sc.map_features[fi];
    int n = static_cast<int>(f.points.size());
    int expected = f.kind == MapFeatureKind::stop_sign ? (n > 0)
                   : n < 2                              ? 0
                   : (f.kind == MapFeatureKind::crosswalk || f.kind == MapFeatureKind::speed_bump ||
                      f.kind == MapFeatureKind::driveway) && !(f.points.front() == f.points.back())
                       ? n
                       : n - 1;
    EXPECT_EQ(vectors_per_feature[fi], expected) << "feature " << fi;
  }
  std::printf("real map: %zu features -> %zu segments\n", sc.map_features.size(), segs.size());
}

}  // namespace
}  // namespace ss
