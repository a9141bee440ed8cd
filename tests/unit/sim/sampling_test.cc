#include "engine/sim/sampling.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace ss {
namespace {

std::vector<int> histogram(const std::vector<float>& logits, double t, double p, int draws, uint64_t seed = 1) {
  Rng rng(seed);
  std::vector<int> h(logits.size());
  for (int i = 0; i < draws; ++i) ++h[sample_token(logits, t, p, rng)];
  return h;
}

TEST(Sampling, FollowsTheSoftmax) {
  const std::vector<float> logits = {0.0f, std::log(2.0f), std::log(7.0f)};  // probabilities 0.1, 0.2, 0.7
  const auto h = histogram(logits, 1.0, 1.0, 100000);
  EXPECT_NEAR(h[0] / 1e5, 0.1, 0.01);
  EXPECT_NEAR(h[1] / 1e5, 0.2, 0.01);
  EXPECT_NEAR(h[2] / 1e5, 0.7, 0.01);
}

TEST(Sampling, TopPKeepsTheNucleus) {
  const std::vector<float> logits = {0.0f, std::log(2.0f), std::log(7.0f)};
  // 0.7 < 0.75: the nucleus needs the second token too; the least likely is never drawn.
  const auto h = histogram(logits, 1.0, 0.75, 20000);
  EXPECT_EQ(h[0], 0);
  EXPECT_NEAR(h[2] / 2e4, 7.0 / 9, 0.02);
  const auto top1 = histogram(logits, 1.0, 0.5, 1000);
  EXPECT_EQ(top1[2], 1000);
}

TEST(Sampling, TemperatureSharpensAndFlattens) {
  const std::vector<float> logits = {0.0f, 1.0f};
  const auto cold = histogram(logits, 0.1, 1.0, 10000);
  const auto hot = histogram(logits, 100.0, 1.0, 10000);
  EXPECT_GT(cold[1], 9990);  // e^10 : 1
  EXPECT_NEAR(hot[1] / 1e4, 0.5, 0.03);
}

TEST(Sampling, NeverDrawsMaskedTokensAndRepeatsForASeed) {
  const std::vector<float> logits = {-INFINITY, 0.0f, -INFINITY, 0.0f};
  const auto h = histogram(logits, 1.0, 0.95, 5000);
  EXPECT_EQ(h[0] + h[2], 0);
  EXPECT_EQ(histogram(logits, 1.0, 0.95, 500, 7), histogram(logits, 1.0, 0.95, 500, 7));
  EXPECT_NE(histogram({0, 0, 0, 0}, 1.0, 1.0, 500, 7), histogram({0, 0, 0, 0}, 1.0, 1.0, 500, 8));
}

TEST(Rng, KnownSequenceAndUniformRange) {
  Rng a(42), b(42);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(a.next(), b.next());
  Rng c(1);
  double lo = 1, hi = 0;
  for (int i = 0; i < 10000; ++i) {
    double u = c.uniform();
    lo = std::min(lo, u), hi = std::max(hi, u);
  }
  EXPECT_GE(lo, 0.0);
  EXPECT_LT(hi, 1.0);
  EXPECT_LT(lo, 0.001);
  EXPECT_GT(hi, 0.999);
}

}  // namespace
}  // namespace ss
