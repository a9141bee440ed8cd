#include "engine/sim/sampling.h"

#include <gtest/gtest.h>

#include <algorithm>
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

// A motion-sized vocabulary whose logits take a few values (so the nucleus ends inside a group of ties, which the
// token order breaks): exactly the nucleus found by sorting is ever drawn, each member at its share of the mass.
TEST(Sampling, NucleusOfALargeVocabularyWithTies) {
  const int n = 1089;
  std::vector<float> logits(n);
  for (int i = 0; i < n; ++i) logits[i] = static_cast<float>((i * 37) % 5);  // values 0..4, interleaved
  std::vector<int> order(n);
  for (int i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](int a, int b) { return logits[a] > logits[b] || (logits[a] == logits[b] && a < b); });
  double total = 0, mass = 0;
  for (float l : logits) total += std::exp(l - 4.0);
  const double top_p = 0.8;
  std::vector<bool> in(n, false);
  for (int k = 0; k < n && (k == 0 || mass < top_p * total); ++k) {
    in[order[k]] = true;
    mass += std::exp(logits[order[k]] - 4.0);
  }
  const int draws = 400000;
  const auto h = histogram(logits, 1.0, top_p, draws);
  int members = 0;
  double worst = 0;  // largest relative error of a top-logit member's frequency
  for (int i = 0; i < n; ++i) {
    if (!in[i]) {
      ASSERT_EQ(h[i], 0) << "token " << i << " lies outside the nucleus";
      continue;
    }
    ++members;
    if (logits[i] == 4.0f) worst = std::max(worst, std::abs(h[i] / (draws / mass) - 1.0));
  }
  EXPECT_GT(members, 200);
  EXPECT_LT(members, n);
  EXPECT_LT(worst, 0.15);  // about 1,700 draws each: a few percent of noise
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

// The draw given acceptance: refused tokens never come, the accepted keep their relative odds, whether the first
// draws find one (likely acceptance) or it is the last token left (a token the draws almost never hit).
TEST(Sampling, SampleTokenIfIsTheDistributionGivenAcceptance) {
  const std::vector<float> logits = {std::log(1.0f), std::log(2.0f), std::log(3.0f), std::log(4.0f)};
  Rng rng(5);
  std::vector<int> h(4);
  for (int i = 0; i < 40000; ++i) ++h[sample_token_if(logits, 1.0, 1.0, rng, [](int t) { return t == 0 || t == 2; })];
  EXPECT_EQ(h[1] + h[3], 0);
  EXPECT_NEAR(h[0] / 4e4, 0.25, 0.01);
  EXPECT_NEAR(h[2] / 4e4, 0.75, 0.01);

  std::vector<float> rare(1089, 0.0f);
  rare[7] = -8.0f;  // p about 3e-4 / 1089: drawn after nearly every other token was refused
  for (int i = 0; i < 100; ++i) {
    std::vector<int> asked(rare.size());
    EXPECT_EQ(sample_token_if(rare, 1.0, 1.0, rng, [&](int t) { return ++asked[t], t == 7; }), 7);
    EXPECT_EQ(*std::max_element(asked.begin(), asked.end()), 1) << "a token is asked about at most once";
  }
}

// Its first draw is sample_token's (same stream), so a taken first draw changes nothing; a refused one is not asked
// again.
TEST(Sampling, SampleTokenIfAsksOnlyTheTokensItDraws) {
  std::vector<float> logits(1089, 0.0f);
  for (int t = 0; t < 10; ++t) logits[t] = 12.0f;  // ten tokens hold nearly all the mass
  Rng a(9), b(9);
  EXPECT_EQ(sample_token_if(logits, 1.0, 1.0, a, [](int) { return true; }), sample_token(logits, 1.0, 1.0, b));
  for (int i = 0; i < 50; ++i) {
    int asked = 0;
    const int t = sample_token_if(logits, 1.0, 1.0, a, [&](int t) { return ++asked, t >= 5; });
    EXPECT_GE(t, 5);
    EXPECT_LE(asked, 6) << "at most the five refused tokens of the ten, then one taken (the rest: 1e-2 of the mass)";
  }
}

TEST(Sampling, SampleTokenIfStaysInTheNucleusAndSaysWhenNothingPasses) {
  const std::vector<float> logits = {0.0f, std::log(2.0f), std::log(7.0f)};  // 0.1, 0.2, 0.7
  Rng rng(2);
  // Top-p 0.75 keeps tokens 2 and 1: token 0 is outside the nucleus, so accepting only it is accepting nothing.
  EXPECT_EQ(sample_token_if(logits, 1.0, 0.75, rng, [](int t) { return t == 0; }), -1);
  EXPECT_EQ(sample_token_if(logits, 1.0, 1.0, rng, [](int) { return false; }), -1);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(sample_token_if(logits, 1.0, 0.75, rng, [](int t) { return t != 2; }), 1);
}

}  // namespace
}  // namespace ss
