#include "engine/model/mask.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "engine/model/attention.h"

namespace ss {
namespace {

DecoderToken tok(TokenKind kind, int step, int64_t object = kNoObject, int64_t seq = 0) {
  DecoderToken t;
  t.kind = kind;
  t.step = step;
  t.object = object;
  t.seq = seq;
  return t;
}

constexpr int W = 10;

TEST(Mask, LightTokens) {
  const DecoderToken q = tok(TokenKind::light, 5, light_object(0));
  EXPECT_TRUE(may_attend(q, tok(TokenKind::light, 5, light_object(3)), W));   // every light at t
  EXPECT_TRUE(may_attend(q, tok(TokenKind::light, 2, light_object(0)), W));   // the same light earlier
  EXPECT_FALSE(may_attend(q, tok(TokenKind::light, 4, light_object(1)), W));  // not other lights earlier
  EXPECT_TRUE(may_attend(q, tok(TokenKind::motion, 4, 7), W));                // every motion at t-1
  EXPECT_FALSE(may_attend(q, tok(TokenKind::motion, 3, 7), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::motion, 5, 7), W));               // not later groups of the step
  EXPECT_FALSE(may_attend(q, tok(TokenKind::relative_state, 5, 7), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::sos, 4), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::light, 6, light_object(0)), W));  // never the future
}

TEST(Mask, AgentStateTokens) {
  const DecoderToken q = tok(TokenKind::map_segment, 5, 7, 100);
  EXPECT_TRUE(may_attend(q, tok(TokenKind::soa, 5, 7, 98), W));               // causal within the group
  EXPECT_TRUE(may_attend(q, tok(TokenKind::relative_state, 5, 3, 90), W));    // earlier agents of the group
  EXPECT_TRUE(may_attend(q, tok(TokenKind::sos, 5, kNoObject, 80), W));
  EXPECT_TRUE(may_attend(q, q, W));                                           // itself
  EXPECT_FALSE(may_attend(q, tok(TokenKind::soa, 5, 9, 101), W));             // not later in the group
  EXPECT_TRUE(may_attend(q, tok(TokenKind::light, 5, light_object(2), 10), W));
  EXPECT_TRUE(may_attend(q, tok(TokenKind::motion, 4, 3), W));                // all motion at t-1
  EXPECT_FALSE(may_attend(q, tok(TokenKind::motion, 3, 3), W));               // others' older motion: no
  EXPECT_TRUE(may_attend(q, tok(TokenKind::motion, 3, 7), W));                // its own: yes
  EXPECT_TRUE(may_attend(q, tok(TokenKind::relative_state, 2, 7), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::relative_state, 2, 3), W));
  EXPECT_TRUE(may_attend(q, tok(TokenKind::eos, 2), W));                      // earlier SOS and EOS
  EXPECT_TRUE(may_attend(q, tok(TokenKind::sos, 1), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::light, 4, light_object(2)), W));  // not earlier lights
  EXPECT_FALSE(may_attend(q, tok(TokenKind::motion, 5, 3, 200), W));          // not this step's motion
}

TEST(Mask, MotionTokens) {
  const DecoderToken q = tok(TokenKind::motion, 5, 7, 300);
  EXPECT_TRUE(may_attend(q, tok(TokenKind::motion, 5, 3, 310), W));  // every motion at t, either side
  EXPECT_TRUE(may_attend(q, tok(TokenKind::light, 5, light_object(0)), W));
  EXPECT_TRUE(may_attend(q, tok(TokenKind::relative_state, 5, 7), W));  // own agent-state tokens up to t
  EXPECT_TRUE(may_attend(q, tok(TokenKind::soa, 1, 7), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::relative_state, 5, 3), W));  // not others'
  EXPECT_TRUE(may_attend(q, tok(TokenKind::motion, 2, 7), W));          // own earlier motion
  EXPECT_FALSE(may_attend(q, tok(TokenKind::motion, 4, 3), W));         // not others' earlier motion
  EXPECT_FALSE(may_attend(q, tok(TokenKind::sos, 5), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::light, 4, light_object(0)), W));
}

TEST(Mask, NothingReachesPastTheWindow) {
  const DecoderToken q = tok(TokenKind::motion, 20, 7);
  EXPECT_TRUE(may_attend(q, tok(TokenKind::motion, 11, 7), W));
  EXPECT_FALSE(may_attend(q, tok(TokenKind::motion, 10, 7), W));
  EXPECT_FALSE(may_attend(tok(TokenKind::sos, 20), tok(TokenKind::eos, 10), W));
}

TEST(Neighbours, SpatialPairs) {
  DecoderToken a = tok(TokenKind::motion, 1, 1), b = tok(TokenKind::motion, 1, 2);
  EXPECT_FALSE(is_spatial_pair(a, b));  // no positions
  a.has_pose = b.has_pose = true;
  EXPECT_TRUE(is_spatial_pair(a, b));
  b.object = 1;
  EXPECT_FALSE(is_spatial_pair(a, b));  // own history is always visible
}

TEST(Neighbours, NearestWithinRadiusKeepsTheClosestEight) {
  NeighbourLimit limit{4, 10.0, 2};
  std::vector<double> d = {30, 5, 12, 1, 8, 3, 50};
  std::vector<int64_t> order = {0, 1, 2, 3, 4, 5, 6};
  // Nearest first: 1 (3), 5 (5)... within 10 m: d=1,3,5,8 -> positions 3,5,1,4; capped at 4.
  EXPECT_EQ(nearest_within(d, order, limit), (std::vector<int>{1, 3, 4, 5}));
  std::vector<double> far = {30, 20, 40};
  EXPECT_EQ(nearest_within(far, std::vector<int64_t>{0, 1, 2}, limit), (std::vector<int>{0, 1}));  // always 2
  std::vector<double> ties = {2, 2, 2};
  EXPECT_EQ(nearest_within(ties, std::vector<int64_t>{9, 3, 5}, {1, 10, 0}), (std::vector<int>{1}));  // by order
}

// The rule as the paper states it (sort everything by distance, then cut), against which the selection is checked.
std::vector<int> nearest_within_by_sorting(const std::vector<double>& d, const std::vector<int64_t>& order,
                                           const NeighbourLimit& limit) {
  std::vector<int> idx(d.size());
  for (size_t i = 0; i < d.size(); ++i) idx[i] = static_cast<int>(i);
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return d[a] < d[b] || (d[a] == d[b] && order[a] < order[b]); });
  size_t kept = 0;
  const size_t cap = std::min(d.size(), static_cast<size_t>(limit.k));
  while (kept < cap && (kept < static_cast<size_t>(limit.always) || d[idx[kept]] <= limit.radius)) ++kept;
  idx.resize(kept);
  std::sort(idx.begin(), idx.end());
  return idx;
}

TEST(Neighbours, SelectionEqualsSortingAndCutting) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 2000; ++trial) {
    const int n = static_cast<int>(rng() % 300);
    const NeighbourLimit limit{1 + static_cast<int>(rng() % 160), static_cast<double>(rng() % 80),
                               static_cast<int>(rng() % 12)};
    std::vector<double> d(n);
    std::vector<int64_t> order(n);
    for (int i = 0; i < n; ++i) {
      d[i] = static_cast<double>(rng() % 100);  // whole metres: many ties, some exactly on the radius
      order[i] = i;                             // the tie-break key is unique (a sequence number, a segment index)
    }
    std::shuffle(order.begin(), order.end(), rng);
    ASSERT_EQ(nearest_within(d, order, limit), nearest_within_by_sorting(d, order, limit))
        << "n " << n << " k " << limit.k << " radius " << limit.radius << " always " << limit.always;
  }
}

TEST(Relations, TranslationAndRotationInvariant) {
  const Anchor q(true, {10, 20, 0.3}, 5), k(true, {13, 24, -0.2}, 3);
  const RelationFeatures f = relation_features(q, k);
  for (const auto& [dx, dy, rot] : {std::tuple{1000.0, -500.0, 0.0}, std::tuple{-3.0, 7.0, 1.2}}) {
    auto move = [&](Anchor a) {
      Vec2 p = rotate({a.pose.x, a.pose.y}, rot) + Vec2{dx, dy};
      return Anchor(a.has_pose, {p.x, p.y, a.pose.heading + rot}, a.step);
    };
    const RelationFeatures g = relation_features(move(q), move(k));
    for (int i = 0; i < kRelationFeatures; ++i) EXPECT_NEAR(f[i], g[i], 1e-5) << i;
  }
  EXPECT_NEAR(f[2], 0.5f, 1e-6);        // 5 m away, in units of 10 m
  EXPECT_NEAR(f[5], 2.0f / 5, 1e-6);    // 2 steps
  EXPECT_EQ(f[6], 1.0f);
  const RelationFeatures none = relation_features(Anchor(false, {}, 5), k);
  EXPECT_EQ(none[0], 0.0f);
  EXPECT_EQ(none[6], 0.0f);
  EXPECT_NEAR(none[5], 0.4f, 1e-6);
}

}  // namespace
}  // namespace ss
