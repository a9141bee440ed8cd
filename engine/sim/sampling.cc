#include "engine/sim/sampling.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <functional>
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

// The tokens' probabilities after temperature (unnormalised), with the nucleus moved to the front; returns its size.
int nucleus(std::span<const float> logits, double temperature, double top_p, std::vector<Candidate>& c) {
  const int n = static_cast<int>(logits.size());
  // exp(l / T - max) for all tokens at once (vectorised); -inf logits give 0.
  const Eigen::Map<const Eigen::ArrayXf> l(logits.data(), n);
  const float inv_t = static_cast<float>(1.0 / temperature);
  const Eigen::ArrayXf p = ((l - l.maxCoeff()) * inv_t).exp();
  c.resize(n);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    c[i] = {std::isfinite(p[i]) ? p[i] : 0.0f, i};
    sum += c[i].p;
  }
  return top_p < 1.0 ? select_nucleus(c, top_p * sum) : n;
}

// One draw over c[0, keep), walked in order (deterministic for given candidates).
int draw(const std::vector<Candidate>& c, int keep, Rng& rng) {
  double sum = 0;
  for (int k = 0; k < keep; ++k) sum += c[k].p;
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

}  // namespace

int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng) {
  std::vector<Candidate> c;
  const int keep = nucleus(logits, temperature, top_p, c);
  return draw(c, keep, rng);
}

int sample_token_if(std::span<const float> logits, double temperature, double top_p, Rng& rng,
                    const std::function<bool(int)>& accept) {
  std::vector<Candidate> c;
  const int keep = nucleus(logits, temperature, top_p, c);
  // Draws until one is accepted: exactly the distribution given acceptance, and cheap when acceptance is likely.
  // After kLazyDraws refusals, `accept` is asked of every token once and the draw is over those it takes.
  constexpr int kLazyDraws = 8;
  for (int k = 0; k < kLazyDraws; ++k)
    if (const int t = draw(c, keep, rng); accept(t)) return t;
  const auto end = std::stable_partition(c.begin(), c.begin() + keep,
                                         [&](const Candidate& x) { return x.p > 0 && accept(x.token); });
  const int accepted = static_cast<int>(end - c.begin());
  return accepted > 0 ? draw(c, accepted, rng) : -1;
}

}  // namespace ss
