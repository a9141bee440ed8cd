#include "engine/tokens/motion.h"

#include <gtest/gtest.h>

#include <random>

namespace ss {
namespace {

TEST(MotionGrid, TokenLayout) {
  EXPECT_EQ(kMotionVocab, 1089);
  EXPECT_EQ(kMotionStart, 1089);
  EXPECT_DOUBLE_EQ(motion_accel(0), -10);
  EXPECT_DOUBLE_EQ(motion_yaw_rate(0), -kPi / 2);
  EXPECT_DOUBLE_EQ(motion_accel(1088), 10);
  EXPECT_DOUBLE_EQ(motion_yaw_rate(1088), kPi / 2);
  const int centre = motion_token(16, 16);
  EXPECT_EQ(centre, 544);
  EXPECT_DOUBLE_EQ(motion_accel(centre), 0);
  EXPECT_DOUBLE_EQ(motion_yaw_rate(centre), 0);
  EXPECT_DOUBLE_EQ(motion_accel(motion_token(17, 0)), 0.625);           // 20 / 32 per bin
  EXPECT_NEAR(motion_yaw_rate(motion_token(0, 17)), kPi / 32, 1e-15);   // pi / 32 per bin
}

TEST(Bicycle, HandComputedSteps) {
  KinematicState s{0, 0, 0, 10};
  KinematicState n = bicycle_step(s, 2, 0);
  EXPECT_DOUBLE_EQ(n.speed, 11);
  EXPECT_DOUBLE_EQ(n.x, 5.25);  // mean speed 10.5 for 0.5 s
  EXPECT_DOUBLE_EQ(n.y, 0);
  KinematicState turn = bicycle_step(s, 0, kPi / 4);
  EXPECT_NEAR(turn.heading, kPi / 8, 1e-15);
  EXPECT_NEAR(turn.x, 5 * std::cos(kPi / 16), 1e-12);  // along the mean heading
  EXPECT_NEAR(turn.y, 5 * std::sin(kPi / 16), 1e-12);
  KinematicState back{0, 0, kPi - 0.1, 2};
  KinematicState wrapped = bicycle_step(back, -2, kPi / 2);  // heading crosses +pi
  EXPECT_NEAR(wrapped.heading, -kPi + kPi / 4 - 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(wrapped.speed, 1);
  EXPECT_NEAR(wrapped.x, 0.75 * std::cos(kPi - 0.1 + kPi / 8), 1e-12);
}

TEST(MotionFit, RecoversGridControlsExactly) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> token(0, kMotionVocab - 1);
  std::vector<StepState> steps;
  KinematicState s{100, -50, 0.3, 8};
  std::vector<int> truth = {kMotionStart};
  steps.push_back({s.x, s.y, s.heading, s.speed * std::cos(s.heading), s.speed * std::sin(s.heading), 4.5, 2, 1.6, true});
  for (int t = 1; t < 19; ++t) {
    int tok = token(rng);
    s = apply_motion_token(s, tok);
    truth.push_back(tok);
    steps.push_back({s.x, s.y, s.heading, 0, 0, 4.5, 2, 1.6, true});
  }
  MotionTrack m = tokenize_motion(steps);
  EXPECT_EQ(m.tokens, truth);
  for (int t = 0; t < 19; ++t) EXPECT_LT(m.ace[t], 1e-9) << t;
}

TEST(MotionFit, StandingStillIsTheCentreToken) {
  MotionFit f = fit_motion_token({5, 5, 1, 0}, {5, 5, 1}, 4, 2);
  EXPECT_EQ(f.token, motion_token(16, 16));
  EXPECT_NEAR(f.ace, 0, 1e-12);
}

TEST(MotionFit, BetweenBinsPicksTheNearest) {
  // 0.2 m/s^2 is nearer 0 than 0.625; a yaw rate of 0.04 rad/s is nearer 0 than pi/32 (0.098).
  KinematicState from{0, 0, 0, 10};
  KinematicState truth = bicycle_step(from, 0.2, 0.04);
  MotionFit f = fit_motion_token(from, {truth.x, truth.y, truth.heading}, 4, 2);
  EXPECT_EQ(f.token, motion_token(16, 16));
  EXPECT_GT(f.ace, 0);
  EXPECT_LT(f.ace, 0.1);
}

TEST(MotionTrack, StartOnAppearanceAndAfterGaps) {
  std::vector<StepState> steps(6);
  for (int t : {1, 2, 4, 5}) steps[t] = {t * 5.0, 0, 0, 10, 0, 4, 2, 1.5, true};
  MotionTrack m = tokenize_motion(steps);
  EXPECT_EQ(m.tokens[0], -1);
  EXPECT_EQ(m.tokens[1], kMotionStart);
  EXPECT_EQ(m.tokens[2], motion_token(16, 16));  // 10 m/s for 0.5 s: 5 m, no acceleration
  EXPECT_EQ(m.tokens[3], -1);
  EXPECT_EQ(m.tokens[4], kMotionStart);
  EXPECT_EQ(m.reconstructed[4].x, 20);  // the true state, not a continuation
  EXPECT_TRUE(std::isnan(m.ace[3]));
  EXPECT_EQ(m.ace[4], 0);
}

TEST(MotionTrack, RollsForwardOnTheReconstruction) {
  // A truth between bins at every step: the reconstruction must not drift, because each step's token is chosen from
  // the reconstructed state, which corrects the previous step's error.
  std::vector<StepState> steps;
  KinematicState s{0, 0, 0, 5};
  for (int t = 0; t < 19; ++t) {
    steps.push_back({s.x, s.y, s.heading, s.speed * std::cos(s.heading), s.speed * std::sin(s.heading), 4, 2, 1.5, true});
    s = bicycle_step(s, 0.3, 0.05);  // half-way between grid lines in both directions
  }
  MotionTrack m = tokenize_motion(steps);
  for (int t = 1; t < 19; ++t) EXPECT_LT(m.ace[t], 0.08) << t;
}

}  // namespace
}  // namespace ss
