// Likelihood estimators of the WOSAC metrics (metrics-spec.md A7): a histogram of the simulated values with
// additive smoothing, scored at the logged value; the Bernoulli estimator is the same histogram over {0, 1}.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace ss {

struct HistogramConfig {
  double min = 0, max = 0;
  int bins = 1;
  double pseudo_count = 0;  // added to every bin, so a value the rollouts never produced is unlikely, not impossible
};

// The bin of a value: values are clipped to [min, max]; bin k holds e_k <= x < e_{k+1}, max falls in the last bin.
// NaN falls in the last bin, as in the official code (metrics-spec.md A9.1).
int histogram_bin(const HistogramConfig& c, double x);

// Bin probabilities P_k = (count_k + a) / (N + B a) of the sim values.
std::vector<double> histogram_probabilities(const HistogramConfig& c, std::span<const double> sim);

// log P of each log value's bin under the histogram of `sim`.
std::vector<double> histogram_log_likelihood(const HistogramConfig& c, std::span<const double> log,
                                             std::span<const double> sim);

// The Bernoulli estimator: a 2-bin histogram over [-0.5, 1.5].
HistogramConfig bernoulli_config(double pseudo_count);
double bernoulli_log_likelihood(double pseudo_count, bool log, std::span<const uint8_t> sim);

// The ten WOSAC 2025 features, in the order of the meta-metric.
enum RealismFeature : int {
  kLinearSpeed, kLinearAcceleration, kAngularSpeed, kAngularAcceleration,
  kDistanceToNearestObject, kCollision, kTimeToCollision,
  kDistanceToRoadEdge, kOffroad, kTrafficLightViolation,
  kNumRealismFeatures
};

struct FeatureConfig {
  const char* name;       // also the JSON key stem (name + "_likelihood")
  bool bernoulli;
  HistogramConfig histogram;
  double weight;          // meta-metric weight; the ten sum to 1
};

// challenge_2025_sim_agents_config: bins, pseudo-counts and weights.
const std::array<FeatureConfig, kNumRealismFeatures>& wosac_2025_config();

}  // namespace ss
