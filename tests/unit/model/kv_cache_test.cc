// KvCache storage: rows written and read back in both precisions, across ring growth and eviction.
#include "engine/model/kv_cache.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace ss {
namespace {

DecoderToken token_at(int step) {
  DecoderToken t;
  t.step = step;
  return t;
}

void fill(KvCache& c, int step, int n) {
  const int first = c.size();
  c.reserve(first + n);
  std::vector<float> rows(static_cast<size_t>(n) * c.d_model);
  // Column 0: the token's step; column j: j + i / 64. Both exact in half floats.
  for (int i = 0; i < n; ++i) {
    rows[i * c.d_model] = static_cast<float>(step);
    for (int j = 1; j < c.d_model; ++j) rows[i * c.d_model + j] = static_cast<float>(j) + static_cast<float>(i) / 64;
  }
  for (int l = 0; l < c.layers(); ++l) {
    c.write_keys(l, first, rows.data(), n);
    c.write_values(l, first, rows.data(), n);
  }
  for (int i = 0; i < n; ++i) {
    c.tokens.push_back(token_at(step));
    c.anchors.emplace_back();
  }
}

class KvCacheTest : public ::testing::TestWithParam<KvPrecision> {};

TEST_P(KvCacheTest, RowsSurviveGrowthAndEviction) {
  KvCache c;
  c.init(2, 16, GetParam());
  EXPECT_EQ(c.layers(), 2);
  int peak = 0;
  for (int step = 0; step < 12; ++step) {
    c.evict_before(step - 3);  // a window of 4 steps
    fill(c, step, 5 + step);
    peak = std::max(peak, c.size());
  }
  std::vector<float> k(16), v(16);
  for (int j = 0; j < c.size(); ++j) {
    c.read_key(1, j, k.data());
    c.read_value(0, j, v.data());
    EXPECT_EQ(k[0], static_cast<float>(c.tokens[j].step)) << "token " << j;
    for (int col = 1; col < 16; ++col) {
      EXPECT_EQ(k[col] - col, k[1] - 1) << "token " << j;
      EXPECT_EQ(v[col], k[col]);
    }
  }
  // The ring holds the window with an eighth to spare, not twice it.
  EXPECT_LE(c.capacity, std::max(peak * 9 / 8, 16));
}

TEST(KvCache, HalfStorageHoldsHalfTheBytes) {
  KvCache a, b;
  a.init(4, 128, KvPrecision::fp32);
  b.init(4, 128, KvPrecision::fp16);
  fill(a, 0, 300);
  fill(b, 0, 300);
  const size_t token_bytes = a.tokens.capacity() * sizeof(DecoderToken) + a.anchors.capacity() * sizeof(Anchor);
  EXPECT_EQ(b.bytes() - token_bytes, (a.bytes() - token_bytes) / 2);
}

INSTANTIATE_TEST_SUITE_P(Precisions, KvCacheTest, ::testing::Values(KvPrecision::fp32, KvPrecision::fp16));

}  // namespace
}  // namespace ss
