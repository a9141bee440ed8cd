// The session's random number generator: xoshiro256** (small state, so a session's save holds it in 32 bytes, and
// the same sequence on every platform, unlike the standard library's distributions).
#pragma once

#include <array>
#include <cstdint>

namespace ss {

struct Rng {
  std::array<uint64_t, 4> s{};

  explicit Rng(uint64_t seed = 0);
  uint64_t next();
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  bool operator==(const Rng&) const = default;
};

}  // namespace ss
