// Histogram and Bernoulli estimators and the 2025 configuration.
#include "offline/eval/estimators.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace ss {
namespace {

TEST(Estimators, BinsClipAndEdges) {
  const HistogramConfig c = wosac_2025_config()[kLinearSpeed].histogram;  // [0, 25], 10 bins of 2.5
  EXPECT_EQ(histogram_bin(c, 0.0), 0);
  EXPECT_EQ(histogram_bin(c, 2.4999), 0);
  EXPECT_EQ(histogram_bin(c, 2.5), 1);  // a value on an edge opens the next bin
  EXPECT_EQ(histogram_bin(c, 24.99), 9);
  EXPECT_EQ(histogram_bin(c, 25.0), 9);  // the maximum falls in the last bin
  EXPECT_EQ(histogram_bin(c, 1e10), 9);  // clipped
  EXPECT_EQ(histogram_bin(c, -3.0), 0);
  EXPECT_EQ(histogram_bin(c, std::numeric_limits<double>::quiet_NaN()), 9);  // metrics-spec A9.1
  const HistogramConfig a = wosac_2025_config()[kAngularSpeed].histogram;  // [-0.628, 0.628], 11 bins
  EXPECT_EQ(histogram_bin(a, 0.0), 5);
}

TEST(Estimators, SmoothedProbabilities) {
  const HistogramConfig c = wosac_2025_config()[kLinearSpeed].histogram;
  const std::vector<double> sim = {1, 1, 3};
  const std::vector<double> p = histogram_probabilities(c, sim);
  // (count + 0.1) / (3 + 10 x 0.1)
  EXPECT_DOUBLE_EQ(p[0], 2.1 / 4);
  EXPECT_DOUBLE_EQ(p[1], 1.1 / 4);
  for (int k = 2; k < 10; ++k) EXPECT_DOUBLE_EQ(p[k], 0.1 / 4);
  const std::vector<double> log = {0.5, 4, 20};
  const std::vector<double> ll = histogram_log_likelihood(c, log, sim);
  EXPECT_DOUBLE_EQ(ll[0], std::log(2.1 / 4));
  EXPECT_DOUBLE_EQ(ll[1], std::log(1.1 / 4));
  EXPECT_DOUBLE_EQ(ll[2], std::log(0.1 / 4));
}

TEST(Estimators, Bernoulli) {
  const std::vector<uint8_t> sim = {1, 0, 0, 0};
  EXPECT_DOUBLE_EQ(bernoulli_log_likelihood(0.001, true, sim), std::log(1.001 / 4.002));
  EXPECT_DOUBLE_EQ(bernoulli_log_likelihood(0.001, false, sim), std::log(3.001 / 4.002));
}

TEST(Estimators, Config2025) {
  const auto& c = wosac_2025_config();
  double total = 0;
  for (const FeatureConfig& f : c) total += f.weight;
  EXPECT_NEAR(total, 1.0, 1e-12);
  EXPECT_EQ(c[kLinearAcceleration].histogram.bins, 11);
  EXPECT_DOUBLE_EQ(c[kDistanceToRoadEdge].histogram.min, -20.0);
  EXPECT_DOUBLE_EQ(c[kOffroad].weight, 0.25);
  EXPECT_TRUE(c[kTrafficLightViolation].bernoulli);
  EXPECT_DOUBLE_EQ(c[kCollision].histogram.pseudo_count, 0.001);
}

}  // namespace
}  // namespace ss
