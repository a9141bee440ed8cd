#include "engine/sim/sampling.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <vector>

namespace ss {
namespace {

struct Candidate {
  float p;
  int token;
};

// The nucleus: the smallest set of most probable candidates (ties broken by token) whose mass reaches `threshold`.
// Moves it to the front of `c` and returns its size (at least 1). A quickselect driven by mass: each round splits
// the undecided range at a pivot and keeps only the side where the mass crosses the threshold, so it costs O(n)
// on average whether the nucleus holds 3 tokens or 1000 (random weights), instead of a sort.
int select_nucleus(std::vector<Candidate>& c, double threshold) {
  auto before = [](const Candidate& a, const Candidate& b) { return a.p > b.p || (a.p == b.p && a.token < b.token); };
  int lo = 0, hi = static_cast<int>(c.size());  // c[0, lo) is in the nucleus; its end lies in [lo, hi]
  double mass = 0;                              // of c[0, lo)
  while (lo < hi && mass < threshold) {
    const Candidate pivot = c[lo + (hi - lo) / 2];
    const auto first_after =
        std::partition(c.begin() + lo, c.begin() + hi, [&](const Candidate& x) { return before(x, pivot); });
    const int g = static_cast<int>(first_after - c.begin());
    double ahead = 0;  // the candidates before the pivot
    for (int i = lo; i < g; ++i) ahead += c[i].p;
    if (mass + ahead >= threshold) {
      hi = g;  // the nucleus ends among them
      continue;
    }
    // All of them are in, and the pivot is next.
    mass += ahead;
    const auto at = std::find_if(c.begin() + g, c.begin() + hi, [&](const Candidate& x) { return x.token == pivot.token; });
    std::iter_swap(c.begin() + g, at);
    mass += pivot.p;
    lo = g + 1;
  }
  if (lo > 0) return lo;
  std::nth_element(c.begin(), c.begin(), c.end(), before);  // nothing has mass: the first candidate alone
  return 1;
}

}  // namespace

int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng) {
  const int n = static_cast<int>(logits.size());
  // exp(l / T - max) for all tokens at once (vectorised); -inf logits give 0.
  const Eigen::Map<const Eigen::ArrayXf> l(logits.data(), n);
  const float inv_t = static_cast<float>(1.0 / temperature);
  const Eigen::ArrayXf p = ((l - l.maxCoeff()) * inv_t).exp();
  std::vector<Candidate> c(n);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    c[i] = {std::isfinite(p[i]) ? p[i] : 0.0f, i};
    sum += c[i].p;
  }
  int keep = n;
  if (top_p < 1.0) {
    keep = select_nucleus(c, top_p * sum);
    sum = 0;
    for (int k = 0; k < keep; ++k) sum += c[k].p;
  }
  // One draw over the nucleus, walked in the order the selection left it (deterministic for given logits).
  double u = rng.uniform() * sum;
  for (int k = 0; k < keep; ++k) {
    u -= c[k].p;
    if (u < 0) return c[k].token;
  }
  // Rounding left u a hair above zero: the last token with mass.
  for (int k = keep - 1; k >= 0; --k)
    if (c[k].p > 0) return c[k].token;
  return c[0].token;
}

}  // namespace ss
