#include "engine/tokens/agent_state.h"

#include <gtest/gtest.h>

#include <random>

namespace ss {
namespace {

TEST(StateBins, RangesAndRounding) {
  EXPECT_EQ(state_bin(kFieldLength, 0.5), 0);
  EXPECT_EQ(state_bin(kFieldLength, 10), 80);
  EXPECT_EQ(state_bin(kFieldLength, 25), 80);   // clipped
  EXPECT_EQ(state_bin(kFieldVx, -3), 0);        // clipped: vx range is [0, 30]
  EXPECT_EQ(state_bin(kFieldU, 0), 40);
  EXPECT_EQ(state_bin(kFieldU, 0.124), 40);     // bin width 0.25 m: rounds to the nearest
  EXPECT_EQ(state_bin(kFieldU, 0.126), 41);
  EXPECT_DOUBLE_EQ(state_bin_value(kFieldU, 41), 0.25);
  EXPECT_DOUBLE_EQ(state_bin_value(kFieldHeading, 0), -kPi / 2);
  EXPECT_DOUBLE_EQ(state_bin_value(kFieldHeading, 80), kPi / 2);
  EXPECT_DOUBLE_EQ(state_bin_value(kFieldWidth, 40), 1.75);
  for (int f = 0; f < kStateFields; ++f)
    for (int b = 0; b < kStateBins; ++b) EXPECT_EQ(state_bin(f, state_bin_value(f, b)), b) << f << " " << b;
  EXPECT_STREQ(state_field_name(kFieldVy), "vy");
}

TEST(RelativeState, HandComputedAndInverse) {
  Pose anchor{100, 200, kPi / 2};  // a segment heading north
  StepState agent{99, 203, kPi / 2 + 0.1, -1, 5, 4.5, 2, 1.6, true};
  RelativeState rel = relative_state(agent, anchor);
  EXPECT_NEAR(rel[kFieldU], 3, 1e-12);    // 3 m ahead along the segment
  EXPECT_NEAR(rel[kFieldV], 1, 1e-12);    // 1 m to its left (west)
  EXPECT_NEAR(rel[kFieldHeading], 0.1, 1e-12);
  EXPECT_NEAR(rel[kFieldVx], 5, 1e-12);
  EXPECT_NEAR(rel[kFieldVy], 1, 1e-12);
  EXPECT_EQ(rel[kFieldLength], 4.5);
  StepState back = global_state(rel, anchor);
  EXPECT_NEAR(back.x, agent.x, 1e-9);
  EXPECT_NEAR(back.y, agent.y, 1e-9);
  EXPECT_NEAR(back.heading, agent.heading, 1e-12);
  EXPECT_NEAR(back.vx, agent.vx, 1e-12);
  EXPECT_NEAR(back.vy, agent.vy, 1e-12);
  EXPECT_TRUE(back.valid);
}

MapSegment straight_segment(double x, double y, double heading) {
  MapSegment s;
  s.pose = {x, y, heading};
  Vec2 d{std::cos(heading) * 2.5, std::sin(heading) * 2.5};
  s.points = {{x - d.x, y - d.y, 0}, {x + d.x, y + d.y, 0}};
  s.length = 5;
  return s;
}

TEST(AgentStateTokens, AnchorRespectsHeading) {
  // Two lanes 3 m apart, opposite directions; the agent is nearer the westbound one but drives east.
  std::vector<MapSegment> segs = {straight_segment(0, 0, 0), straight_segment(0, 3, kPi)};
  SegmentIndex index(segs);
  StepState agent{1, 2, 0.05, 10, 0, 4.5, 2, 1.5, true};
  auto tok = encode_agent_state(agent, index, segs);
  ASSERT_TRUE(tok.ok()) << tok.status();
  EXPECT_EQ(tok->segment, 0);
  EXPECT_EQ(tok->bins[kFieldU], state_bin(kFieldU, 1));
  EXPECT_EQ(tok->bins[kFieldV], state_bin(kFieldV, 2));
  StepState dec = decode_agent_state(*tok, segs);
  EXPECT_NEAR(dec.x, 1, 0.125 + 1e-9);   // within half a bin of 0.25 m
  EXPECT_NEAR(dec.y, 2, 0.125 + 1e-9);
  EXPECT_NEAR(dec.heading, 0.05, kPi / 160 + 1e-9);
  agent.heading = kPi - 0.05;  // now it drives west: the other lane
  EXPECT_EQ(encode_agent_state(agent, index, segs)->segment, 1);
}

TEST(AgentStateTokens, RoundTripErrorIsAtMostHalfABin) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<MapSegment> segs;
  for (int i = 0; i < 50; ++i) segs.push_back(straight_segment(20 * u(rng), 20 * u(rng), kPi * u(rng)));
  SegmentIndex index(segs);
  for (int n = 0; n < 2000; ++n) {
    StepState a{20 * u(rng), 20 * u(rng), kPi * u(rng), 0, 0, 5 + 4 * u(rng), 1.75 + u(rng), 2 + u(rng), true};
    auto tok = encode_agent_state(a, index, segs);
    ASSERT_TRUE(tok.ok());
    RelativeState rel = relative_state(a, segs[tok->segment].pose);
    for (int f = 0; f < kStateFields; ++f) {
      const FieldRange r = kStateRanges[f];
      if (rel[f] < r.min || rel[f] > r.max) continue;
      EXPECT_LE(std::abs(rel[f] - state_bin_value(f, tok->bins[f])), (r.max - r.min) / 160 + 1e-9) << f;
    }
  }
}

TEST(AgentStateTokens, EmptyMapIsAnError) {
  std::vector<MapSegment> none;
  SegmentIndex index(none);
  auto tok = encode_agent_state({0, 0, 0, 0, 0, 4, 2, 1.5, true}, index, none);
  EXPECT_EQ(tok.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(tok.status().message().find("empty"), std::string::npos);
}

}  // namespace
}  // namespace ss
