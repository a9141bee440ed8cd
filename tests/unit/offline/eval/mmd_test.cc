// Gaussian-kernel MMD (one bandwidth) and the initial-state attribute sets.
#include "offline/eval/mmd.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

TEST(Mmd, HandComputed) {
  // X = {0}, Y = {1}: D = [[0, 1], [1, 0]], h = 2 / (4 - 2) = 1; MMD^2 = 1 + 1 - 2 e^-1.
  EXPECT_NEAR(gaussian_mmd2({{0.0}}, {{1.0}}), 2 - 2 * std::exp(-1.0), 1e-12);
  // X = {0, 0}, Y = {2}: D sums to 2 x 2 x 4 = 16 over 6 distinct pairs: h = 8/3.
  const double k = std::exp(-4 / (16.0 / 6));
  EXPECT_NEAR(gaussian_mmd2({{0.0}, {0.0}}, {{2.0}}), 1 + 1 - 2 * k, 1e-12);
}

TEST(Mmd, SameSampleIsZeroAndEmptyIsUndefined) {
  const std::vector<std::vector<double>> x = {{1, 2}, {3, -1}, {0, 0}};
  EXPECT_NEAR(gaussian_mmd2(x, x), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(gaussian_mmd2({{5.0}}, {{5.0}}), 0.0);  // zero bandwidth: all points equal
  EXPECT_TRUE(std::isnan(gaussian_mmd2({}, x)));
  // Further apart: larger.
  EXPECT_LT(gaussian_mmd2({{0.0}, {1.0}}, {{0.5}, {1.5}}), gaussian_mmd2({{0.0}, {1.0}}, {{5.0}, {6.0}}));
}

TEST(Mmd, AttributesInTheSdcFrame) {
  // The same agents seen from a rotated, moved frame: the MMD compares attributes in that frame, so moving both
  // sets together changes nothing, while turning only the generated agents changes heading and velocity.
  const Pose frame{100, 50, kPi / 2};
  std::vector<InitialAgent> log = {{100, 60, kPi / 2, 4.5, 2, 0, 5}, {90, 50, kPi, 4, 1.8, -3, 0}};
  std::vector<InitialAgent> gen = log;
  const InitialStateMmd same = initial_state_mmd(gen, log, frame);
  EXPECT_NEAR(same.position, 0, 1e-12);
  EXPECT_NEAR(same.heading, 0, 1e-12);
  EXPECT_NEAR(same.velocity, 0, 1e-12);
  for (InitialAgent& a : gen) a.heading += 1.0, std::swap(a.vx, a.vy);
  const InitialStateMmd turned = initial_state_mmd(gen, log, frame);
  EXPECT_NEAR(turned.position, 0, 1e-12);
  EXPECT_NEAR(turned.size, 0, 1e-12);
  EXPECT_GT(turned.heading, 0.01);
  EXPECT_GT(turned.velocity, 0.01);
}

TEST(Mmd, StrictSet) {
  Scenario map;
  MapFeature lane;
  lane.kind = MapFeatureKind::lane;
  lane.points = {{-100, 0, 0}, {100, 0, 0}};
  map.map_features.push_back(lane);
  const Pose frame{0, 0, 0};
  std::vector<InitialAgent> agents = {
      {10, 1, 0, 4, 2, 0, 0, ObjectType::vehicle},       // kept
      {10, 1, 0, 1, 1, 0, 0, ObjectType::pedestrian},    // not a vehicle
      {10, 8, 0, 4, 2, 0, 0, ObjectType::vehicle},       // 8 m from the lane
      {10, 1, kPi / 2, 4, 2, 0, 0, ObjectType::vehicle}, // across the lane
      {60, 0, 0, 4, 2, 0, 0, ObjectType::vehicle},       // outside the 50 m box
      {-5, -2, kPi, 4, 2, 0, 0, ObjectType::vehicle},    // against the lane direction: more than pi/4 off
  };
  const std::vector<InitialAgent> s = strict_set(agents, frame, map);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_DOUBLE_EQ(s[0].x, 10);
  // At most 32, nearest first.
  std::vector<InitialAgent> many;
  for (int i = 0; i < 40; ++i) many.push_back({40.0 - i, 0, 0, 4, 2, 0, 0, ObjectType::vehicle});
  const std::vector<InitialAgent> capped = strict_set(many, frame, map);
  ASSERT_EQ(capped.size(), 32u);
  EXPECT_DOUBLE_EQ(capped[0].x, 1.0);
}

}  // namespace
}  // namespace ss
