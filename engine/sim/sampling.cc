#include "engine/sim/sampling.h"

#include <Eigen/Core>
#include <immintrin.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

namespace ss {
namespace {

// A token and its mass as one 64-bit key: the mass's bits above, the token's complement below. Masses are >= 0 (and
// never -0), so keys compare as integers the way the nucleus ranks tokens (more mass first, then the lower token),
// and the partition below runs eight candidates to an AVX-512 vector.
struct Candidate {
  uint64_t key;

  static Candidate of(float p, int token) {
    return {static_cast<uint64_t>(std::bit_cast<uint32_t>(p)) << 32 | ~static_cast<uint32_t>(token)};
  }
  float p() const { return std::bit_cast<float>(static_cast<uint32_t>(key >> 32)); }
  int token() const { return static_cast<int>(~static_cast<uint32_t>(key)); }
};

// Reorders c[lo, hi), out of place and stably, around the key `pivot` (one of them): the keys above it, then the
// pivot, then the keys below; returns the pivot's index. Adds the mass of the keys above it to `ahead`, summed in
// eight lanes by position (lane = (i - lo) % 8), then lane 0 to 7: one order, so one result, with or without AVX-512.
int partition_around(std::vector<Candidate>& c, std::vector<Candidate>& below, int lo, int hi, uint64_t pivot,
                     double& ahead) {
  below.resize(hi - lo);
  alignas(64) double lanes[8] = {};
  int left = lo, right = 0;
  int i = lo;
#if defined(__AVX512F__)
  // In place: c[left..] is written no further than the block just loaded (left <= i), whose keys are in x already.
  const __m512i pv = _mm512_set1_epi64(static_cast<long long>(pivot));
  __m512d acc = _mm512_setzero_pd();
  auto* data = reinterpret_cast<uint64_t*>(c.data());
  auto* rest = reinterpret_cast<uint64_t*>(below.data());
  for (; i < hi; i += 8) {
    const __mmask8 valid = hi - i >= 8 ? __mmask8(0xff) : static_cast<__mmask8>((1u << (hi - i)) - 1);
    const __m512i x = _mm512_maskz_loadu_epi64(valid, data + i);
    const __mmask8 gt = _mm512_mask_cmpgt_epu64_mask(valid, x, pv), lt = _mm512_mask_cmplt_epu64_mask(valid, x, pv);
    _mm512_mask_compressstoreu_epi64(data + left, gt, x);
    _mm512_mask_compressstoreu_epi64(rest + right, lt, x);
    left += std::popcount(static_cast<unsigned>(gt));
    right += std::popcount(static_cast<unsigned>(lt));
    const __m256 p = _mm256_castsi256_ps(_mm512_cvtepi64_epi32(_mm512_srli_epi64(x, 32)));
    acc = _mm512_add_pd(acc, _mm512_maskz_cvtps_pd(gt, p));
  }
  _mm512_store_pd(lanes, acc);
#else
  for (; i < hi; ++i) {
    const Candidate x = c[i];
    if (x.key > pivot) {
      c[left++] = x;
      lanes[(i - lo) % 8] += x.p();
    } else if (x.key < pivot) {
      below[right++] = x;
    }
  }
#endif
  double sum = 0;
  for (double l : lanes) sum += l;
  ahead += sum;
  c[left] = {pivot};
  std::copy_n(below.begin(), right, c.begin() + left + 1);
  return left;
}

// The nucleus: the smallest set of most probable candidates (ties broken by token) whose mass reaches `threshold`.
// Moves it to the front of `c` and returns its size (at least 1). A quickselect driven by mass: each round splits
// the undecided range at a pivot and keeps only the side where the mass crosses the threshold, so it costs O(n)
// on average whether the nucleus holds 3 tokens or 1000 (random weights), instead of a sort.
int select_nucleus(std::vector<Candidate>& c, double threshold) {
  thread_local std::vector<Candidate> below;
  int lo = 0, hi = static_cast<int>(c.size());  // c[0, lo) is in the nucleus; its end lies in [lo, hi]
  double mass = 0;                              // of c[0, lo)
  while (lo < hi && mass < threshold) {
    const Candidate pivot = c[lo + (hi - lo) / 2];
    double ahead = 0;  // the candidates before the pivot
    const int g = partition_around(c, below, lo, hi, pivot.key, ahead);
    if (mass + ahead >= threshold) {
      hi = g;  // the nucleus ends among them
      continue;
    }
    // All of them are in, and the pivot is next.
    mass += ahead;
    mass += pivot.p();
    lo = g + 1;
  }
  if (lo > 0) return lo;
  // Nothing has mass: the first candidate alone.
  std::iter_swap(c.begin(), std::max_element(c.begin(), c.end(), [](Candidate a, Candidate b) { return a.key < b.key; }));
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
    c[i] = Candidate::of(std::isfinite(p[i]) ? p[i] : 0.0f, i);
    sum += c[i].p();
  }
  return top_p < 1.0 ? select_nucleus(c, top_p * sum) : n;
}

// One draw over c[0, keep), walked in order (deterministic for given candidates): its index, or -1 when none of
// them has mass.
int draw(const std::vector<Candidate>& c, int keep, Rng& rng) {
  double sum = 0;
  for (int k = 0; k < keep; ++k) sum += c[k].p();
  double u = rng.uniform() * sum;  // drawn even without mass, so the stream does not depend on it
  if (!(sum > 0)) return -1;
  for (int k = 0; k < keep; ++k) {
    u -= c[k].p();
    if (u < 0) return k;
  }
  // Rounding left u a hair above zero: the last candidate with mass.
  for (int k = keep - 1; k >= 0; --k)
    if (c[k].p() > 0) return k;
  return -1;
}

// The candidates' masses in a Fenwick tree: a draw and a removal cost O(log n) each, so drawing without
// replacement until a token is taken does not walk the nucleus once per draw.
class MassTree {
 public:
  MassTree(const std::vector<Candidate>& c, int n)
      : sum_(n + 1, 0.0), mass_(n), top_(static_cast<int>(std::bit_floor(static_cast<unsigned>(n)))) {
    for (int i = 0; i < n; ++i) {
      mass_[i] = c[i].p();
      alive_ += c[i].p() > 0;
      sum_[i + 1] += c[i].p();
      if (const int up = (i + 1) + ((i + 1) & -(i + 1)); up <= n) sum_[up] += sum_[i + 1];
    }
  }
  // Takes candidate k out; false once no candidate with mass is left.
  bool remove(int k) {
    if (mass_[k] > 0) {
      for (int i = k + 1; i < static_cast<int>(sum_.size()); i += i & -i) sum_[i] -= mass_[k];
      mass_[k] = 0;
      --alive_;
    }
    return alive_ > 0;
  }
  // A candidate with mass, drawn in proportion to it (only while remove() says some are left).
  int draw(Rng& rng) const {
    const int n = static_cast<int>(mass_.size());
    double total = 0;
    for (int i = n; i > 0; i -= i & -i) total += sum_[i];
    double u = rng.uniform() * total;
    int pos = 0;  // the candidates before pos hold at most u
    for (int step = top_; step > 0; step /= 2)
      if (pos + step <= n && sum_[pos + step] <= u) {
        pos += step;
        u -= sum_[pos];
      }
    // Rounding can land past the end or on a removed candidate: the nearest one with mass.
    for (int k = std::min(pos, n - 1); k >= 0; --k)
      if (mass_[k] > 0) return k;
    for (int k = pos; k < n; ++k)
      if (mass_[k] > 0) return k;
    return 0;  // unreachable while alive_ > 0
  }

 private:
  std::vector<double> sum_;   // 1-based Fenwick sums
  std::vector<float> mass_;   // each candidate's mass, 0 once removed
  int alive_ = 0;             // candidates with mass left
  int top_ = 0;               // the largest power of two <= n (the search's first step)
};

}  // namespace

int sample_token(std::span<const float> logits, double temperature, double top_p, Rng& rng) {
  std::vector<Candidate> c;
  const int keep = nucleus(logits, temperature, top_p, c);
  const int k = draw(c, keep, rng);
  return c[k < 0 ? 0 : k].token();  // no mass at all (every logit -inf): the first token
}

int sample_token_if(std::span<const float> logits, double temperature, double top_p, Rng& rng,
                    const std::function<bool(int)>& accept) {
  std::vector<Candidate> c;
  const int keep = nucleus(logits, temperature, top_p, c);
  // The first draw is sample_token's; when refused, the draws go on without replacement: a refused token leaves the
  // candidates and the next draw is over the rest. The tokens `accept` takes keep their relative odds at every draw,
  // so the first one drawn is a draw from the distribution given acceptance. Each token is asked at most once, and
  // only those drawn: with random weights a pass of `accept` over the whole nucleus was 8 % of a step.
  const int first = draw(c, keep, rng);
  if (first < 0) return -1;
  if (accept(c[first].token())) return c[first].token();
  MassTree left(c, keep);
  for (int k = first; left.remove(k);) {
    k = left.draw(rng);
    if (accept(c[k].token())) return c[k].token();
  }
  return -1;
}

}  // namespace ss
