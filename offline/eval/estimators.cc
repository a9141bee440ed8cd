#include "offline/eval/estimators.h"

#include <algorithm>
#include <cmath>

namespace ss {

int histogram_bin(const HistogramConfig& c, double x) {
  if (std::isnan(x)) return c.bins - 1;
  x = std::clamp(x, c.min, c.max);
  // The edge comparisons of the official histogram, not a division, so values on an edge land where it puts them.
  const double width = (c.max - c.min) / c.bins;
  int k = std::clamp(static_cast<int>((x - c.min) / width), 0, c.bins - 1);
  while (k > 0 && x < c.min + k * width) --k;
  while (k + 1 < c.bins && x >= c.min + (k + 1) * width) ++k;
  return k;
}

std::vector<double> histogram_probabilities(const HistogramConfig& c, std::span<const double> sim) {
  std::vector<double> p(c.bins, c.pseudo_count);
  for (double v : sim) p[histogram_bin(c, v)] += 1;
  const double total = static_cast<double>(sim.size()) + c.bins * c.pseudo_count;
  for (double& v : p) v /= total;
  return p;
}

std::vector<double> histogram_log_likelihood(const HistogramConfig& c, std::span<const double> log,
                                             std::span<const double> sim) {
  const std::vector<double> p = histogram_probabilities(c, sim);
  std::vector<double> out;
  out.reserve(log.size());
  // A NaN log value has no bin in the official histogram and its argmax falls back to bin 0; such values are
  // masked out when scoring anyway.
  for (double v : log) out.push_back(std::log(p[std::isnan(v) ? 0 : histogram_bin(c, v)]));
  return out;
}

HistogramConfig bernoulli_config(double pseudo_count) { return {-0.5, 1.5, 2, pseudo_count}; }

double bernoulli_log_likelihood(double pseudo_count, bool log, std::span<const uint8_t> sim) {
  std::vector<double> values(sim.begin(), sim.end());
  const double x = log ? 1.0 : 0.0;
  return histogram_log_likelihood(bernoulli_config(pseudo_count), {&x, 1}, values)[0];
}

const std::array<FeatureConfig, kNumRealismFeatures>& wosac_2025_config() {
  static const std::array<FeatureConfig, kNumRealismFeatures> config = {{
      {"linear_speed", false, {0.0, 25.0, 10, 0.1}, 0.05},
      {"linear_acceleration", false, {-12.0, 12.0, 11, 0.1}, 0.05},
      {"angular_speed", false, {-0.628, 0.628, 11, 0.1}, 0.05},
      {"angular_acceleration", false, {-3.14, 3.14, 11, 0.1}, 0.05},
      {"distance_to_nearest_object", false, {-5.0, 40.0, 10, 0.1}, 0.10},
      {"collision_indication", true, {-0.5, 1.5, 2, 0.001}, 0.25},
      {"time_to_collision", false, {0.0, 5.0, 10, 0.1}, 0.10},
      {"distance_to_road_edge", false, {-20.0, 40.0, 10, 0.1}, 0.05},
      {"offroad_indication", true, {-0.5, 1.5, 2, 0.001}, 0.25},
      {"traffic_light_violation", true, {-0.5, 1.5, 2, 0.001}, 0.05},
  }};
  return config;
}

}  // namespace ss
