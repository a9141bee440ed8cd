#include "engine/sim/sampling.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ss {

int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng) {
  const int n = static_cast<int>(logits.size());
  double max = -INFINITY;
  for (float l : logits) max = std::max(max, static_cast<double>(l));
  struct Candidate {
    double p;
    int token;
  };
  std::vector<Candidate> c(n);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    c[i] = {std::isfinite(logits[i]) ? std::exp((logits[i] - max) / temperature) : 0.0, i};
    sum += c[i].p;
  }
  int keep = n;
  if (top_p < 1.0) {
    // The nucleus in order of probability (ties by token): select the best `end` candidates, sort the newly selected
    // ones, and widen only while the mass is short of top_p (a peaked distribution sorts a few dozen, not all).
    auto before = [](const Candidate& a, const Candidate& b) { return a.p > b.p || (a.p == b.p && a.token < b.token); };
    double mass = 0;
    keep = 0;
    for (int begin = 0, end = std::min(n, 32); begin < n; begin = end, end = std::min(n, end * 4)) {
      std::nth_element(c.begin() + begin, c.begin() + end - 1, c.end(), before);
      std::sort(c.begin() + begin, c.begin() + end, before);
      while (keep < end && (keep == 0 || mass < top_p * sum)) mass += c[keep++].p;
      if (keep < end) break;  // the nucleus closed inside this batch
      if (mass >= top_p * sum) break;
    }
    sum = mass;
  }
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
