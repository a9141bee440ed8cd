// set_relation_columns: the relation MLP run over many key sets at once gives each set the same bits as run on that
// set alone (what a restored session needs: it rebuilds its key sets in other calls than the first run made them
// in), with the MLP's products in fp32 and, where the CPU has AVX512-BF16, in bf16. Where the bf16 products run on
// AVX512-BF16 (not AMX, whose tiles add in another order than the fused pass), also the bits relation_columns gives.
#include "engine/model/attention.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "engine/model/matmul_bf16.h"

namespace ss {
namespace {

void check_sets_at_once(bool bf16) {
  std::mt19937 rng(7);
  std::normal_distribution<float> normal(0.0f, 0.5f);
  const int r = 32;
  std::vector<float> w1(r * kRelationFeatures), b1(r), w2(r * r), b2(r);
  for (auto* v : {&w1, &b1, &w2, &b2})
    for (float& x : *v) x = normal(rng);
  RelationParams p{{w1.data(), b1.data(), r, kRelationFeatures}, {w2.data(), b2.data(), r, r}};
  const Bf16Weight packed = bf16 ? bf16_pack(w2.data(), r, r) : Bf16Weight{};
  if (bf16) p.fc2.bf16 = &packed;

  // Sets of 0, 1, 2 ... 300 keys, 6,000 rows in all: several chunks, and sets on both sides of a chunk's edge.
  std::vector<int> sizes = {0, 1, 2, 3, 128, 0, 1, 300, 17, 64};
  std::uniform_int_distribution<int> size(0, 200);
  for (int total = 0; total < 6000; total += sizes.back()) sizes.push_back(size(rng));
  std::vector<std::vector<float>> features;
  for (int n : sizes) {
    std::vector<float>& f = features.emplace_back(static_cast<size_t>(n) * kRelationFeatures);
    for (float& x : f) x = normal(rng);
  }
  std::vector<QueryKeys> sets(sizes.size());
  std::vector<QueryKeys*> pointers;
  for (QueryKeys& s : sets) pointers.push_back(&s);
  set_relation_columns(pointers, features, p);

  const bool product_bits = !bf16 || bf16_kernel() == Bf16Kernel::avx512_bf16;
  for (size_t i = 0; i < sizes.size(); ++i) {
    QueryKeys alone;
    QueryKeys* one[] = {&alone};
    set_relation_columns(one, std::span(&features[i], 1), p);
    ASSERT_EQ(sets[i].relation.rows(), alone.relation.rows()) << "set " << i;
    ASSERT_EQ(sets[i].relation.cols(), sizes[i]) << "set " << i;
    EXPECT_EQ(std::memcmp(sets[i].relation.data(), alone.relation.data(), alone.relation.size() * sizeof(float)), 0)
        << "set " << i << " (" << sizes[i] << " keys): other bits than the set alone";
    if (!product_bits) continue;
    const Mat f = Eigen::Map<const Mat>(features[i].data(), sizes[i], kRelationFeatures);
    const Mat want = relation_columns(f, p);
    ASSERT_EQ(want.rows(), alone.relation.rows()) << "set " << i;
    EXPECT_EQ(std::memcmp(sets[i].relation.data(), want.data(), want.size() * sizeof(float)), 0)
        << "set " << i << " (" << sizes[i] << " keys): other bits than relation_columns alone";
  }
}

TEST(RelationColumns, ManySetsAtOnceEqualEachAloneFp32) { check_sets_at_once(false); }

TEST(RelationColumns, ManySetsAtOnceEqualEachAloneBf16) {
  if (!bf16_products_available()) GTEST_SKIP() << "no AVX512-BF16 on this CPU";
  check_sets_at_once(true);
}

}  // namespace
}  // namespace ss
