// Kinematic features: the test vector of metrics-spec.md A2 and hand-computed cases.
#include "offline/eval/features/kinematic.h"

#include <gtest/gtest.h>

#include <cmath>

#include "engine/geometry/geometry.h"

namespace ss {
namespace {

std::vector<BoxState> track(std::vector<double> x, std::vector<double> h, std::vector<double> y = {},
                            std::vector<double> z = {}) {
  std::vector<BoxState> s(x.size());
  for (size_t t = 0; t < x.size(); ++t) {
    s[t].x = x[t];
    s[t].heading = h[t];
    if (!y.empty()) s[t].y = y[t];
    if (!z.empty()) s[t].z = z[t];
    s[t].valid = true;
  }
  return s;
}

TEST(Kinematic, SpecTestVector) {
  // x = [5, 6, 8, 9, 9], h = [0, 1, 3, 2, 0], dt = 1.
  const KinematicFeatures k = kinematic_features(track({5, 6, 8, 9, 9}, {0, 1, 3, 2, 0}), 1.0);
  EXPECT_TRUE(std::isnan(k.linear_speed[0]));
  EXPECT_DOUBLE_EQ(k.linear_speed[1], 1.5);
  EXPECT_DOUBLE_EQ(k.linear_speed[2], 1.5);
  EXPECT_DOUBLE_EQ(k.linear_speed[3], 0.5);
  EXPECT_TRUE(std::isnan(k.linear_speed[4]));
  EXPECT_DOUBLE_EQ(k.linear_acceleration[2], -0.5);
  for (int t : {0, 1, 3, 4}) EXPECT_TRUE(std::isnan(k.linear_acceleration[t])) << t;
  EXPECT_DOUBLE_EQ(k.angular_speed[1], 1.5);
  EXPECT_DOUBLE_EQ(k.angular_speed[2], 0.5);
  EXPECT_DOUBLE_EQ(k.angular_speed[3], -1.5);
  EXPECT_DOUBLE_EQ(k.angular_acceleration[2], -1.5);
  for (int t : {0, 1, 3, 4}) EXPECT_TRUE(std::isnan(k.angular_acceleration[t])) << t;
}

TEST(Kinematic, SpeedIsThreeDimensionalAndScaledByDt) {
  // Moving 3 m in x and 4 m in z per frame at 10 Hz: 50 m/s.
  const KinematicFeatures k = kinematic_features(track({0, 3, 6}, {0, 0, 0}, {}, {0, 4, 8}), 0.1);
  EXPECT_NEAR(k.linear_speed[1], 50.0, 1e-9);
}

TEST(Kinematic, HeadingWrapsAcrossPi) {
  // Turning left through +-pi at 0.1 rad per frame: no jump of 2 pi.
  const double a = kPi - 0.1;
  const KinematicFeatures k = kinematic_features(track({0, 0, 0}, {a, wrap_angle(a + 0.1), wrap_angle(a + 0.2)}), 0.1);
  EXPECT_NEAR(k.angular_speed[1], 1.0, 1e-9);
}

TEST(Kinematic, AngularAccelerationOfSteadyTurnIsZero) {
  std::vector<double> h;
  for (int t = 0; t < 7; ++t) h.push_back(wrap_angle(3.0 + 0.5 * t));
  const KinematicFeatures k = kinematic_features(track(std::vector<double>(7, 0.0), h), 0.1);
  for (int t = 2; t <= 4; ++t) EXPECT_NEAR(k.angular_acceleration[t], 0.0, 1e-9) << t;
  EXPECT_NEAR(k.angular_speed[3], 5.0, 1e-9);
}

TEST(Kinematic, ValidityMasks) {
  const std::vector<uint8_t> v = {1, 1, 1, 0, 1, 1, 1, 1};
  // speed: both neighbours valid; never at the ends.
  EXPECT_EQ(speed_validity(v), (std::vector<uint8_t>{0, 1, 0, 1, 0, 1, 1, 0}));
  // acceleration: both neighbouring speeds valid.
  EXPECT_EQ(acceleration_validity(v), (std::vector<uint8_t>{0, 0, 1, 0, 1, 0, 0, 0}));
}

}  // namespace
}  // namespace ss
