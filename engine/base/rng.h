// The one random-number generator, seed mixer and hash of the project. Written here rather than taken from <random>,
// whose distributions the C++ standard leaves to each library: a seed must give the same rollout, weights and
// dataset bytes on every build. (Two classes once shared the name ss::Rng: a one-definition-rule violation that gave
// Debug builds another sequence. Keep this the only one.)
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

namespace ss {

// splitmix64's output function: mixes a seed (and a stream number) into well-spread 64-bit values, so nearby
// inputs give unrelated outputs.
inline uint64_t mix_seed(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
inline uint64_t mix_seed(uint64_t seed, uint64_t stream) { return mix_seed(mix_seed(seed) ^ mix_seed(~stream)); }

// FNV-1a, 64 bits: a content hash that is the same on every platform, unlike std::hash. `h` continues a hash.
constexpr uint64_t kFnv1aOffset = 0xCBF29CE484222325ull;
inline uint64_t fnv1a64_bytes(const void* data, size_t n, uint64_t h = kFnv1aOffset) {
  const auto* c = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < n; ++i) h = (h ^ c[i]) * 0x100000001B3ull;
  return h;
}
inline uint64_t fnv1a64(std::string_view s, uint64_t h = kFnv1aOffset) { return fnv1a64_bytes(s.data(), s.size(), h); }

// xoshiro256** (Blackman and Vigna), seeded by the splitmix64 sequence its authors recommend. Its 32-byte state is
// public so a session's save can hold it.
struct Rng {
  std::array<uint64_t, 4> s{};

  explicit Rng(uint64_t seed = 0) {
    for (uint64_t& w : s) w = mix_seed(seed), seed += 0x9E3779B97F4A7C15ull;  // never all zero
  }
  uint64_t next() {
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
  }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [lo, hi]; rejection keeps it exactly uniform.
  int64_t integer(int64_t lo, int64_t hi) {
    const uint64_t range = static_cast<uint64_t>(hi - lo) + 1;
    if (range == 0) return static_cast<int64_t>(next());
    const uint64_t limit = UINT64_MAX - UINT64_MAX % range;
    uint64_t v;
    do v = next();
    while (v >= limit);
    return lo + static_cast<int64_t>(v % range);
  }
  bool chance(double p) { return uniform() < p; }
  template <class T>
  const T& pick(std::span<const T> items) {
    return items[integer(0, static_cast<int64_t>(items.size()) - 1)];
  }
  template <class T>
  const T& pick(const std::vector<T>& items) {
    return pick(std::span<const T>(items));
  }
  // An index drawn with the given (non-negative, not all zero) weights.
  size_t weighted(std::span<const double> weights) {
    double total = 0;
    for (double w : weights) total += w;
    double r = uniform() * total;
    for (size_t i = 0; i < weights.size(); ++i) {
      if (r < weights[i]) return i;
      r -= weights[i];
    }
    return weights.size() - 1;
  }
  template <class T>
  void shuffle(std::vector<T>* v) {
    for (size_t i = v->size(); i > 1; --i) std::swap((*v)[i - 1], (*v)[integer(0, static_cast<int64_t>(i) - 1)]);
  }
  bool operator==(const Rng&) const = default;

 private:
  static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
};

}  // namespace ss
