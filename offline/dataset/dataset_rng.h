// The dataset generator's seeding of the one random-number generator (engine/base/rng.h): each state word is mix_seed
// of the word before, as the generator seeded its generator before the project's RNGs were made one. Kept so that
// `dataset sumo --seed S` still writes the bytes it always wrote: the bundled sample in data/ is such a run, and
// tests/tools/dataset_test.sh regenerates it and compares its MANIFEST byte for byte.
#pragma once

#include <cstdint>

#include "engine/base/rng.h"

namespace ss {

inline Rng dataset_rng(uint64_t seed) {
  Rng r;
  for (uint64_t& w : r.s) w = seed = mix_seed(seed);
  return r;
}

}  // namespace ss
