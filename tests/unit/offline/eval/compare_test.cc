// Paired comparisons with bootstrap intervals, on hand-made values whose difference and interval are known.
#include "offline/eval/compare.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(EvalCompare, QuantileInterpolates) {
  const std::vector<double> v = {1, 2, 3, 4, 5};
  EXPECT_DOUBLE_EQ(quantile(v, 0.0), 1);
  EXPECT_DOUBLE_EQ(quantile(v, 1.0), 5);
  EXPECT_DOUBLE_EQ(quantile(v, 0.5), 3);
  EXPECT_DOUBLE_EQ(quantile(v, 0.1), 1.4);  // numpy.quantile([1..5], 0.1)
  EXPECT_TRUE(std::isnan(quantile(std::vector<double>{}, 0.5)));
}

TEST(EvalCompare, KnownDifferences) {
  PairedColumns c;
  c.names = {"shifted", "two_values", "noisy", "sometimes"};
  // shifted: B = A + 0.1 in every scenario, so every resample's difference is 0.1: the interval is [0.1, 0.1].
  // two_values: the difference is 0 in the first two scenarios and 0.2 in the other two: a resample's mean
  //   difference is k * 0.05 (k of 4 draws from the second pair), k ~ Binomial(4, 1/2): the 2.5 % and 97.5 %
  //   quantiles of 10^4 resamples are 0 and 0.2.
  // noisy: A and B differ by +1 or -1 alternately: the mean difference is 0 and the interval straddles it.
  // sometimes: undefined in scenario 0 for B: that scenario does not pair.
  const double a[4][4] = {{0.5, 1, 0, 1}, {0.6, 1, 0, 2}, {0.7, 1, 0, 3}, {0.8, 1, 0, 4}};
  const double b[4][4] = {{0.6, 1, 1, kNaN}, {0.7, 1, -1, 3}, {0.8, 1.2, 1, 4}, {0.9, 1.2, -1, 5}};
  for (int s = 0; s < 4; ++s) {
    c.a.emplace_back(a[s], a[s] + 4);
    c.b.emplace_back(b[s], b[s] + 4);
  }
  const std::vector<CompareMetric> metrics = {{"shifted", {{0, 1.0}}},
                                              {"two_values", {{1, 1.0}}},
                                              {"noisy", {{2, 1.0}}},
                                              {"sometimes", {{3, 1.0}}},
                                              {"weighted", {{0, 1.0}, {1, 3.0}}}};
  auto r = compare_paired(c, metrics, {10000, 1, 0.95});
  ASSERT_TRUE(r.ok()) << r.status();
  const auto& d = *r;
  ASSERT_EQ(d.size(), 5u);
  EXPECT_NEAR(d[0].a, 0.65, 1e-12);
  EXPECT_NEAR(d[0].b, 0.75, 1e-12);
  EXPECT_NEAR(d[0].difference, 0.1, 1e-12);
  EXPECT_NEAR(d[0].low, 0.1, 1e-12);
  EXPECT_NEAR(d[0].high, 0.1, 1e-12);
  EXPECT_EQ(d[0].scenarios, 4);
  EXPECT_NEAR(d[1].difference, 0.1, 1e-12);
  EXPECT_NEAR(d[1].low, 0.0, 1e-12);
  EXPECT_NEAR(d[1].high, 0.2, 1e-12);
  EXPECT_NEAR(d[2].difference, 0.0, 1e-12);
  EXPECT_LT(d[2].low, 0.0);
  EXPECT_GT(d[2].high, 0.0);
  EXPECT_EQ(d[3].scenarios, 3);
  EXPECT_NEAR(d[3].a, 3.0, 1e-12);  // scenarios 1-3 only, for A too (paired)
  EXPECT_NEAR(d[3].difference, 1.0, 1e-12);
  EXPECT_NEAR(d[3].low, 1.0, 1e-12);
  // weighted: (1 x mean0 + 3 x mean1) / 4.
  EXPECT_NEAR(d[4].a, (0.65 + 3 * 1.0) / 4, 1e-12);
  EXPECT_NEAR(d[4].b, (0.75 + 3 * 1.1) / 4, 1e-12);
  EXPECT_LE(d[4].low, d[4].difference);
  EXPECT_GE(d[4].high, d[4].difference);

  // The same seed gives the same interval; the interval of B vs A mirrors that of A vs B.
  auto again = compare_paired(c, metrics, {10000, 1, 0.95});
  EXPECT_EQ((*again)[2].low, d[2].low);
  PairedColumns swapped = c;
  std::swap(swapped.a, swapped.b);
  auto back = compare_paired(swapped, metrics, {10000, 1, 0.95});
  EXPECT_NEAR((*back)[2].low, -d[2].high, 1e-12);
}

TEST(EvalCompare, BadInputs) {
  PairedColumns c;
  c.names = {"x"};
  EXPECT_FALSE(compare_paired(c, std::vector<CompareMetric>{{"x", {{0, 1.0}}}}, {}).ok());  // no scenarios
  c.a = {{1.0}};
  c.b = {{1.0}, {2.0}};
  EXPECT_FALSE(compare_paired(c, std::vector<CompareMetric>{{"x", {{0, 1.0}}}}, {}).ok());  // unpaired
  c.b = {{2.0}};
  EXPECT_FALSE(compare_paired(c, std::vector<CompareMetric>{{"x", {{1, 1.0}}}}, {}).ok());  // no such column
  EXPECT_FALSE(compare_paired(c, std::vector<CompareMetric>{{"x", {{0, 1.0}}}}, {0, 1, 0.95}).ok());
  auto one = compare_paired(c, std::vector<CompareMetric>{{"x", {{0, 1.0}}}}, {100, 1, 0.95});
  ASSERT_TRUE(one.ok());
  EXPECT_DOUBLE_EQ((*one)[0].difference, 1.0);
}

}  // namespace
}  // namespace ss
