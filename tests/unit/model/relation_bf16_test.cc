// The fused relation MLP (engine/model/relation_bf16.h) against the path it replaces: the shallow first layer, bias
// and relu, then the AVX512-BF16 product, bias and relu, transposed. Bit for bit, for the default width and a wider
// one, sets of every length around a vector's sixteen pairs, and each pair's bits the same alone as in its set.
// Skipped on CPUs without AVX512-BF16.
#include "engine/model/relation_bf16.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "engine/model/attention.h"
#include "engine/model/matmul_bf16.h"
#include "engine/model/vocab.h"

namespace ss {
namespace {

struct Layers {
  std::vector<float> w1, b1, w2, b2;
  Bf16Weight w2_bf16;
  LinearParams fc1, fc2;

  Layers(int r, std::mt19937& rng) {
    std::normal_distribution<float> n(0, 0.5f);
    auto fill = [&](std::vector<float>& v, size_t size) {
      v.resize(size);
      for (float& x : v) x = n(rng);
    };
    fill(w1, static_cast<size_t>(r) * kRelationFeatures);
    fill(b1, r);
    fill(w2, static_cast<size_t>(r) * r);
    fill(b2, r);
    w2_bf16 = bf16_pack(w2.data(), r, r);
    fc1 = {w1.data(), b1.data(), r, kRelationFeatures, nullptr};
    fc2 = {w2.data(), b2.data(), r, r, &w2_bf16};
  }
};

// The replaced path, with the AVX512-BF16 product named (an AMX machine's default product sums in another order).
Mat reference(const Mat& f, const Layers& l) {
  Mat h = linear(f, l.fc1);
  relu_inplace(h);
  Mat y(f.rows(), l.fc2.out);
  bf16_linear(h.data(), static_cast<int>(h.rows()), *l.fc2.bf16, y.data(), Bf16Kernel::avx512_bf16);
  y.rowwise() += VecMap(l.fc2.bias, l.fc2.out);
  relu_inplace(y);
  return y.transpose();
}

Mat random_features(int n, std::mt19937& rng) {
  std::normal_distribution<float> g(0, 1);
  Mat f(n, kRelationFeatures);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < kRelationFeatures; ++k) f(i, k) = g(rng);
  return f;
}

bool same_bits(const Mat& a, const Mat& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::memcmp(a.data(), b.data(), sizeof(float) * a.size()) == 0;
}

TEST(RelationBf16, MatchesTheProductPathBitForBit) {
  if (!bf16_products_available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  std::mt19937 rng(7);
  for (const int r : {32, 64}) {
    const Layers l(r, rng);
    ASSERT_TRUE(relation_columns_bf16_fits(l.fc1, l.fc2));
    for (const int n : {1, 7, 15, 16, 17, 31, 44, 130}) {
      const Mat f = random_features(n, rng);
      Mat got(r, n);
      relation_columns_bf16(f.data(), n, l.fc1, l.fc2, got.data());
      EXPECT_TRUE(same_bits(got, reference(f, l))) << "r " << r << ", n " << n;
      for (const int j : {0, n / 2, n - 1}) {  // one pair alone: the same bits as in its set
        Mat alone(r, 1);
        relation_columns_bf16(f.row(j).data(), 1, l.fc1, l.fc2, alone.data());
        EXPECT_TRUE(same_bits(alone, Mat(got.col(j)))) << "r " << r << ", n " << n << ", pair " << j;
      }
    }
  }
}

TEST(RelationBf16, FitsOnlyTheLayersItRuns) {
  std::mt19937 rng(8);
  Layers l(32, rng);
  EXPECT_EQ(relation_columns_bf16_fits(l.fc1, l.fc2), bf16_products_available());
  LinearParams fp32 = l.fc2;
  fp32.bf16 = nullptr;  // the fp32 products: the set-by-set path
  EXPECT_FALSE(relation_columns_bf16_fits(l.fc1, fp32));
  LinearParams no_bias = l.fc1;
  no_bias.bias = nullptr;
  EXPECT_FALSE(relation_columns_bf16_fits(no_bias, l.fc2));
}

}  // namespace
}  // namespace ss
