#include "offline/eval/compare.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "engine/base/rng.h"

namespace ss {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Column means of A and B over the scenarios in `draw` (with repeats) where the column is defined in both.
struct Means {
  std::vector<double> a, b;
  std::vector<int> n;
};

Means column_means(const PairedColumns& c, std::span<const int> draw) {
  const size_t cols = c.names.size();
  Means m{std::vector<double>(cols, 0.0), std::vector<double>(cols, 0.0), std::vector<int>(cols, 0)};
  for (int s : draw)
    for (size_t k = 0; k < cols; ++k) {
      const double x = c.a[s][k], y = c.b[s][k];
      if (std::isfinite(x) && std::isfinite(y)) m.a[k] += x, m.b[k] += y, ++m.n[k];
    }
  for (size_t k = 0; k < cols; ++k) {
    m.a[k] = m.n[k] ? m.a[k] / m.n[k] : kNaN;
    m.b[k] = m.n[k] ? m.b[k] / m.n[k] : kNaN;
  }
  return m;
}

double weighted(const std::vector<double>& means, const CompareMetric& metric) {
  double sum = 0, weights = 0;
  for (const auto& [col, w] : metric.terms) sum += w * means[col], weights += w;
  return sum / weights;
}

}  // namespace

double quantile(std::span<const double> sorted, double q) {
  if (sorted.empty()) return kNaN;
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

absl::StatusOr<std::vector<MetricDifference>> compare_paired(const PairedColumns& columns,
                                                             std::span<const CompareMetric> metrics,
                                                             const BootstrapOptions& options) {
  const size_t scenarios = columns.a.size();
  if (scenarios == 0) return absl::InvalidArgumentError("no scenarios to compare");
  if (columns.b.size() != scenarios)
    return absl::InvalidArgumentError(absl::StrCat("A has ", scenarios, " scenarios, B ", columns.b.size()));
  for (size_t s = 0; s < scenarios; ++s)
    if (columns.a[s].size() != columns.names.size() || columns.b[s].size() != columns.names.size())
      return absl::InvalidArgumentError(absl::StrCat("scenario ", s, " does not have one value per column"));
  if (options.resamples < 1) return absl::InvalidArgumentError("the bootstrap needs at least one resample");
  if (!(options.level > 0 && options.level < 1)) return absl::InvalidArgumentError("the interval's level is not in (0, 1)");
  for (const CompareMetric& m : metrics) {
    if (m.terms.empty()) return absl::InvalidArgumentError(absl::StrCat("metric ", m.name, " has no column"));
    for (const auto& [col, w] : m.terms)
      if (col < 0 || col >= static_cast<int>(columns.names.size()) || !(w > 0))
        return absl::InvalidArgumentError(absl::StrCat("metric ", m.name, ": bad column ", col, " or weight ", w));
  }

  std::vector<int> everyone(scenarios);
  for (size_t s = 0; s < scenarios; ++s) everyone[s] = static_cast<int>(s);
  const Means full = column_means(columns, everyone);
  std::vector<MetricDifference> out;
  for (const CompareMetric& m : metrics) {
    MetricDifference d;
    d.name = m.name;
    d.scenarios = std::numeric_limits<int>::max();
    for (const auto& [col, w] : m.terms) d.scenarios = std::min(d.scenarios, full.n[col]);
    d.a = weighted(full.a, m), d.b = weighted(full.b, m), d.difference = d.b - d.a;
    out.push_back(d);
  }

  // The replicates: one draw of scenario indices serves every metric (paired across A and B, and across metrics).
  std::vector<std::vector<double>> diffs(metrics.size());
  Rng rng(options.seed);
  std::vector<int> draw(scenarios);
  for (int r = 0; r < options.resamples; ++r) {
    for (int& s : draw) s = static_cast<int>((static_cast<unsigned __int128>(rng.next()) * scenarios) >> 64);
    const Means m = column_means(columns, draw);
    for (size_t k = 0; k < metrics.size(); ++k) {
      const double x = weighted(m.b, metrics[k]) - weighted(m.a, metrics[k]);
      if (std::isfinite(x)) diffs[k].push_back(x);  // a replicate that drew no scenario defining the metric: skipped
    }
  }
  const double tail = (1 - options.level) / 2;
  for (size_t k = 0; k < metrics.size(); ++k) {
    std::sort(diffs[k].begin(), diffs[k].end());
    out[k].low = quantile(diffs[k], tail);
    out[k].high = quantile(diffs[k], 1 - tail);
  }
  return out;
}

}  // namespace ss
