// The one RNG, seed mixer and hash give the published algorithms' values on every build (these tests also run in a
// Debug build: tests/determinism/debug_build.sh). Expected values come from an independent Python transcription of
// splitmix64 and xoshiro256**, and from FNV-1a's published test vectors.
#include "engine/base/rng.h"

#include <gtest/gtest.h>

#include <set>

namespace ss {
namespace {

TEST(Rng, XoshiroSeededBySplitmixGivesTheReferenceSequence) {
  Rng a(1);
  EXPECT_EQ(a.next(), 0xb3f2af6d0fc710c5ull);
  EXPECT_EQ(a.next(), 0x853b559647364ceaull);
  EXPECT_EQ(a.next(), 0x92f89756082a4514ull);
  Rng b(0);
  EXPECT_EQ(b.next(), 0x99ec5f36cb75f2b4ull);
  EXPECT_EQ(b.next(), 0xbf6e1f784956452aull);
}

TEST(Rng, SeedMixerIsSplitmix64) {
  EXPECT_EQ(mix_seed(0), 0xe220a8397b1dcdafull);
  EXPECT_EQ(mix_seed(1), 0x910a2dec89025cc1ull);
  EXPECT_NE(mix_seed(5, 1), mix_seed(5, 2));
  EXPECT_NE(mix_seed(5, 1), mix_seed(6, 1));
}

TEST(Rng, Fnv1aMatchesThePublishedVectorsAndContinues) {
  EXPECT_EQ(fnv1a64(""), 0xcbf29ce484222325ull);
  EXPECT_EQ(fnv1a64("a"), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(fnv1a64("foobar"), 0x85944171f73967e8ull);
  EXPECT_EQ(fnv1a64("bar", fnv1a64("foo")), fnv1a64("foobar"));
}

TEST(Rng, DrawsStayInTheirRanges) {
  Rng r(7);
  std::set<int64_t> seen;
  for (int i = 0; i < 2000; ++i) {
    const double u = r.uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    const int64_t k = r.integer(-2, 2);
    ASSERT_GE(k, -2);
    ASSERT_LE(k, 2);
    seen.insert(k);
  }
  EXPECT_EQ(seen.size(), 5u);
  const double w[] = {0, 1, 0};
  EXPECT_EQ(r.weighted(w), 1u);
}

}  // namespace
}  // namespace ss
