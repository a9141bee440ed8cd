#include "engine/geometry/geometry.h"

#include <gtest/gtest.h>

#include <vector>

namespace ss {
namespace {

TEST(WrapAngle, MapsIntoHalfOpenRange) {
  EXPECT_DOUBLE_EQ(wrap_angle(0), 0);
  EXPECT_NEAR(wrap_angle(3 * kPi / 2), -kPi / 2, 1e-12);
  EXPECT_NEAR(wrap_angle(-3 * kPi / 2), kPi / 2, 1e-12);
  EXPECT_NEAR(wrap_angle(kPi), -kPi, 1e-12);  // [-pi, pi): +pi maps to -pi
  EXPECT_NEAR(wrap_angle(450 * kPi / 180), kPi / 2, 1e-12);
  EXPECT_NEAR(wrap_angle(-270 * kPi / 180), kPi / 2, 1e-12);
  for (double a = -20; a < 20; a += 0.37) {
    double w = wrap_angle(a);
    EXPECT_GE(w, -kPi);
    EXPECT_LT(w, kPi);
    EXPECT_NEAR(std::cos(w), std::cos(a), 1e-9);
    EXPECT_NEAR(std::sin(w), std::sin(a), 1e-9);
  }
}

TEST(CircularMean, AveragesAcrossTheWrap) {
  std::vector<double> a = {kPi - 0.1, -kPi + 0.1};
  EXPECT_NEAR(std::abs(circular_mean(a)), kPi, 1e-12);
  std::vector<double> b = {0.1, 0.3};
  EXPECT_NEAR(circular_mean(b), 0.2, 1e-12);
  EXPECT_EQ(circular_mean(std::vector<double>{}), 0);
  EXPECT_NEAR(circular_mean2(kPi - 0.1, -kPi + 0.3), -kPi + 0.1, 1e-12);
  EXPECT_NEAR(circular_mean2(-0.2, 0.4), 0.1, 1e-12);
}

TEST(Frames, LocalAndGlobalAreInverse) {
  Pose f{10, -5, kPi / 2};
  Vec2 local = to_local(f, {10, -3});  // 2 m "north" of a frame facing north is 2 m ahead
  EXPECT_NEAR(local.x, 2, 1e-12);
  EXPECT_NEAR(local.y, 0, 1e-12);
  Vec2 back = to_global(f, {1.5, -0.5});
  Vec2 again = to_local(f, back);
  EXPECT_NEAR(again.x, 1.5, 1e-12);
  EXPECT_NEAR(again.y, -0.5, 1e-12);
}

TEST(Box, CornersInOrder) {
  auto c = box_corners({{0, 0, 0}, 4, 2});
  EXPECT_NEAR(c[0].x, 2, 1e-12);   // front-left
  EXPECT_NEAR(c[0].y, 1, 1e-12);
  EXPECT_NEAR(c[1].x, -2, 1e-12);  // rear-left
  EXPECT_NEAR(c[2].y, -1, 1e-12);  // rear-right
  EXPECT_NEAR(c[3].x, 2, 1e-12);   // front-right
  EXPECT_NEAR(c[3].y, -1, 1e-12);
  auto r = box_corners({{1, 1, kPi / 2}, 4, 2});
  EXPECT_NEAR(r[0].x, 0, 1e-12);   // facing +y: front-left is at (-1, +2) from the centre
  EXPECT_NEAR(r[0].y, 3, 1e-12);
}

TEST(Box, AverageCornerError) {
  Box a{{0, 0, 0}, 4, 2};
  EXPECT_DOUBLE_EQ(average_corner_error(a, a), 0);
  Box shifted{{0.3, -0.4, 0}, 4, 2};
  EXPECT_NEAR(average_corner_error(a, shifted), 0.5, 1e-12);
  Box turned{{0, 0, kPi}, 4, 2};  // a half turn moves every corner to its opposite: distance 2 * sqrt(5)
  EXPECT_NEAR(average_corner_error(a, turned), 2 * std::sqrt(5.0), 1e-12);
}

TEST(Box, OverlapBySeparatingAxes) {
  Box a{{0, 0, 0}, 4, 2};
  EXPECT_TRUE(boxes_overlap(a, {{3, 0, 0}, 4, 2}));
  EXPECT_FALSE(boxes_overlap(a, {{4.01, 0, 0}, 4, 2}));
  EXPECT_FALSE(boxes_overlap(a, {{4, 0, 0}, 4, 2}));  // touching
  // A rotated box whose bounding box overlaps but which does not: the diagonal case axis-aligned tests get wrong.
  EXPECT_FALSE(boxes_overlap({{0, 0, kPi / 4}, 2, 0.2}, {{1.2, -1.2, kPi / 4}, 2, 0.2}));
  EXPECT_TRUE(boxes_overlap({{0, 0, kPi / 4}, 4, 1}, {{0, 0, -kPi / 4}, 4, 1}));
}

TEST(Polyline, Distances) {
  std::vector<Vec2> line = {{0, 0}, {10, 0}, {10, 10}};
  EXPECT_NEAR(point_polyline_distance({5, 3}, line), 3, 1e-12);
  EXPECT_NEAR(point_polyline_distance({12, 5}, line), 2, 1e-12);
  EXPECT_NEAR(point_polyline_distance({-3, -4}, line), 5, 1e-12);
  EXPECT_NEAR(polyline_length(line), 20, 1e-12);
  EXPECT_NEAR(point_polyline_distance({3, 4}, std::vector<Vec2>{{0, 0}}), 5, 1e-12);
  EXPECT_TRUE(std::isinf(point_polyline_distance({0, 0}, std::vector<Vec2>{})));
  EXPECT_NEAR(point_segment_distance({1, 1}, {0, 0}, {0, 0}), std::sqrt(2.0), 1e-12);
}

}  // namespace
}  // namespace ss
