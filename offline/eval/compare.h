// Two evaluations of the same scenarios compared scenario by scenario: each metric's difference (B - A) with a
// percentile bootstrap interval. Scenarios are resampled with replacement, the same draw for A and B (paired), so
// the interval reflects how much the difference depends on which scenarios were evaluated, not the rollouts' noise
// alone.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"

namespace ss {

// Per-scenario values of both evaluations: a[s][c], b[s][c] for scenario s and column c; NaN where undefined.
struct PairedColumns {
  std::vector<std::string> names;
  std::vector<std::vector<double>> a, b;
};

// A metric of the column means: sum of weight x mean over its terms, divided by the sum of the weights (a single
// column with weight 1 is that column's mean; the realism buckets are weighted means of likelihood means, as the
// dataset figures are). A column's mean is over the scenarios where it is defined in both A and B.
struct CompareMetric {
  std::string name;
  std::vector<std::pair<int, double>> terms;  // (column, weight)
};

struct MetricDifference {
  std::string name;
  int scenarios = 0;                   // paired scenarios (for several terms: the fewest of any term)
  double a = 0, b = 0, difference = 0;  // on every paired scenario; difference = b - a
  double low = 0, high = 0;             // the bootstrap interval of the difference (NaN when undefined)
};

struct BootstrapOptions {
  int resamples = 10000;
  uint64_t seed = 1;
  double level = 0.95;
};

// The q-quantile of sorted values, interpolating linearly between order statistics (numpy's default).
double quantile(std::span<const double> sorted, double q);

absl::StatusOr<std::vector<MetricDifference>> compare_paired(const PairedColumns& columns,
                                                             std::span<const CompareMetric> metrics,
                                                             const BootstrapOptions& options);

}  // namespace ss
