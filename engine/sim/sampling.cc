#include "engine/sim/sampling.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

namespace ss {

int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng) {
  const int n = static_cast<int>(logits.size());
  double max = -INFINITY;
  for (float l : logits) max = std::max(max, static_cast<double>(l));
  std::vector<double> p(n);
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += (p[i] = std::isfinite(logits[i]) ? std::exp((logits[i] - max) / temperature) : 0.0);
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  int keep = n;
  if (top_p < 1.0) {
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return p[a] > p[b]; });
    double mass = 0;
    keep = 0;
    while (keep < n && (keep == 0 || mass < top_p * sum)) mass += p[order[keep++]];
    sum = mass;
  }
  double u = rng.uniform() * sum;
  for (int k = 0; k < keep; ++k) {
    u -= p[order[k]];
    if (u < 0) return order[k];
  }
  // Rounding left u a hair above zero: the last token with mass.
  for (int k = keep - 1; k >= 0; --k)
    if (p[order[k]] > 0) return order[k];
  return order[0];
}

}  // namespace ss
