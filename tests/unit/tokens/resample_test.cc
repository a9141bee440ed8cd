#include "engine/tokens/resample.h"

#include <gtest/gtest.h>

#include "engine/geometry/geometry.h"

namespace ss {
namespace {

TEST(Resample, StepCounts) {
  EXPECT_EQ(num_model_steps(91), 19);
  EXPECT_EQ(num_model_steps(1), 1);
  EXPECT_EQ(num_model_steps(0), 0);
  EXPECT_EQ(num_model_steps(95), 19);
  EXPECT_EQ(frame_to_step(10), 2);
  EXPECT_EQ(frame_to_step(90), 18);
  EXPECT_EQ(frame_to_step(11), -1);
}

TEST(Resample, DownsampleTakesEveryFifthFrame) {
  Track t;
  t.states.resize(91);
  for (int f = 0; f < 91; ++f) t.states[f] = {f * 1.0, 0, 0, 4, 2, 1.5, 0.25f, 10, 0, f != 45};
  auto steps = downsample_track(t);
  ASSERT_EQ(steps.size(), 19u);
  EXPECT_EQ(steps[2].x, 10);
  EXPECT_EQ(steps[18].x, 90);
  EXPECT_FALSE(steps[9].valid);  // frame 45
  EXPECT_TRUE(steps[8].valid);
  EXPECT_FLOAT_EQ(steps[0].heading, 0.25f);
}

TEST(Resample, UpsampleInterpolatesPositionVelocityAndHeading) {
  std::vector<StepState> steps(3);
  steps[0] = {0, 0, kPi - 0.1, 10, 0, 4, 2, 1.5, true};
  steps[1] = {5, 10, -kPi + 0.1, 0, 10, 4, 2, 1.5, true};
  steps[2] = {};  // invalid
  auto frames = upsample_states(steps);
  ASSERT_EQ(frames.size(), 11u);
  EXPECT_EQ(frames[0], steps[0]);
  EXPECT_EQ(frames[5], steps[1]);
  EXPECT_NEAR(frames[1].x, 1, 1e-12);
  EXPECT_NEAR(frames[2].y, 4, 1e-12);
  EXPECT_NEAR(frames[3].vx, 4, 1e-12);
  EXPECT_NEAR(frames[3].vy, 6, 1e-12);
  // The heading turns the short way through pi, not through 0.
  for (int f = 0; f <= 5; ++f) EXPECT_GT(std::abs(frames[f].heading), kPi - 0.1 - 1e-9) << f;
  EXPECT_NEAR(std::abs(wrap_angle(frames[2].heading - (kPi - 0.02))), 0, 1e-3);
  for (int f = 6; f < 11; ++f) EXPECT_FALSE(frames[f].valid) << f;
}

TEST(Resample, DownsampleOfUpsampleIsIdentity) {
  std::vector<StepState> steps;
  for (int t = 0; t < 19; ++t) steps.push_back({t * 3.0, t * -1.0, 0.1 * t, 6, -2, 4.5, 1.9, 1.6, t != 7});
  auto frames = upsample_states(steps);
  ASSERT_EQ(frames.size(), 91u);
  for (int t = 0; t < 19; ++t) EXPECT_EQ(frames[t * 5], steps[t]) << t;
}

}  // namespace
}  // namespace ss
