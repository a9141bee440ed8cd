// The bf16 products (engine/model/matmul_bf16.h), with each kernel the CPU has (AVX512-BF16; AMX), against the same
// products in double over the same bf16-rounded inputs, on the shapes the model uses and ragged edges; each row's
// bits independent of its batch. Skipped on CPUs without AVX512-BF16 (the fp32 path is the only one there).
#include "engine/model/matmul_bf16.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "engine/model/linalg.h"

namespace ss {
namespace {

float bf16_round(float f) {  // round to nearest even, as the kernel's conversion
  uint32_t u;
  std::memcpy(&u, &f, 4);
  u += 0x7fff + ((u >> 16) & 1);
  u &= 0xffff0000u;
  std::memcpy(&f, &u, 4);
  return f;
}

Mat random_mat(int rows, int cols, std::mt19937& rng) {
  std::normal_distribution<float> n(0, 1);
  Mat m(rows, cols);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) m(i, j) = n(rng);
  return m;
}

std::vector<Bf16Kernel> kernels() {  // the kernels this CPU has, the default one last
  std::vector<Bf16Kernel> k;
  if (bf16_kernel() >= Bf16Kernel::avx512_bf16) k.push_back(Bf16Kernel::avx512_bf16);
  if (bf16_kernel() == Bf16Kernel::amx) k.push_back(Bf16Kernel::amx);
  return k;
}

class Bf16Products : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!bf16_products_available()) GTEST_SKIP() << "this CPU has no AVX512-BF16";
  }
};

TEST_F(Bf16Products, MatchTheProductOfTheRoundedInputs) {
  std::mt19937 rng(3);
  // rows: one token, a tile and a bit, two blocks and a tail; out: a head (3), ragged, a whole tile multiple; in:
  // tile multiples, and ragged depths (a whole map's 1,093 keys as the depth of the weighted values).
  for (const int rows : {1, 15, 16, 17, 33, 70, 600})  // 600: more than one chunk of rows
    for (const auto& [out, in] : {std::pair{3, 32}, {48, 64}, {130, 128}, {512, 128}, {128, 512}, {32, 1093}, {20, 7}}) {
      const Mat x = random_mat(rows, in, rng), w = random_mat(out, in, rng);
      const Bf16Weight packed = bf16_pack(w.data(), out, in);
      for (const Bf16Kernel kernel : kernels()) {
        Mat y(rows, out);
        bf16_linear(x.data(), rows, packed, y.data(), kernel);
        double worst = 0;
        for (int i = 0; i < rows; ++i)
          for (int o = 0; o < out; ++o) {
            double ref = 0, mag = 0;
            for (int k = 0; k < in; ++k) {
              const double p = static_cast<double>(bf16_round(x(i, k))) * bf16_round(w(o, k));
              ref += p, mag += std::abs(p);
            }
            worst = std::max(worst, std::abs(y(i, o) - ref) / mag);  // fp32 sums: error relative to sum |terms|
          }
        EXPECT_LT(worst, 1e-5) << rows << " x " << in << " -> " << out << ", " << bf16_kernel_name(kernel);
      }
    }
}

TEST_F(Bf16Products, StayCloseToFloatProducts) {
  std::mt19937 rng(5);
  const Mat x = random_mat(40, 128, rng), w = random_mat(96, 128, rng);
  Mat y(40, 96);
  bf16_linear(x.data(), 40, bf16_pack(w.data(), 96, 128), y.data());
  const Mat ref = x * w.transpose();
  // Two roundings to 8 significant bits: about 2^-8 of each term, partly cancelling over 128 terms.
  EXPECT_LT((y - ref).cwiseAbs().maxCoeff() / ref.cwiseAbs().maxCoeff(), 1e-2);
}

TEST_F(Bf16Products, PackAStridedOrTransposedView) {
  std::mt19937 rng(11);
  const Mat v = random_mat(45, 64, rng);  // e.g. 45 keys of width 64; head 1 is columns 32..63
  const Mat x = random_mat(5, 45, rng), q = random_mat(5, 32, rng);
  Mat y(5, 32), scores(5, 45);
  // Weighted values: W = V_h^T (32 x 45), from V's columns; scores: W = K_h (45 x 32), rows of stride 64.
  bf16_linear(x.data(), 5, bf16_pack(v.data() + 32, 32, 45, 1, 64), y.data());
  bf16_linear(q.data(), 5, bf16_pack(v.data() + 32, 45, 32, 64, 1), scores.data());
  const Mat vh = v.middleCols(32, 32);
  const Mat y_copy = [&] { Mat o(5, 32); bf16_linear(x.data(), 5, bf16_pack(Mat(vh.transpose()).data(), 32, 45), o.data()); return o; }();
  const Mat s_copy = [&] { Mat o(5, 45); bf16_linear(q.data(), 5, bf16_pack(Mat(vh).data(), 45, 32), o.data()); return o; }();
  EXPECT_EQ(y, y_copy);
  EXPECT_EQ(scores, s_copy);
  EXPECT_TRUE(y.isApprox(x * vh, 1e-2));
}

TEST_F(Bf16Products, ARowHasTheSameBitsAloneAndInABatch) {
  std::mt19937 rng(7);
  const Mat x = random_mat(50, 64, rng), w = random_mat(200, 64, rng);
  const Bf16Weight packed = bf16_pack(w.data(), 200, 64);
  for (const Bf16Kernel kernel : kernels()) {
    Mat batch(50, 200);
    bf16_linear(x.data(), 50, packed, batch.data(), kernel);
    for (const int r : {0, 17, 31, 32, 49}) {
      Mat alone(1, 200);
      bf16_linear(x.row(r).data(), 1, packed, alone.data(), kernel);
      EXPECT_EQ(std::memcmp(alone.data(), batch.row(r).data(), 200 * sizeof(float)), 0)
          << "row " << r << ", " << bf16_kernel_name(kernel);
    }
  }
}

TEST_F(Bf16Products, TheDefaultKernelIsTheFastestTheCpuHas) {
  EXPECT_EQ(bf16_kernel(), kernels().back());
  const Mat x = Mat::Random(3, 32), w = Mat::Random(5, 32);
  const Bf16Weight packed = bf16_pack(w.data(), 5, 32);
  Mat a(3, 5), b(3, 5);
  bf16_linear(x.data(), 3, packed, a.data());
  bf16_linear(x.data(), 3, packed, b.data(), bf16_kernel());
  EXPECT_EQ(a, b);
}

TEST_F(Bf16Products, LinearUsesThemWhenTheWeightIsPacked) {
  std::mt19937 rng(9);
  const Mat x = random_mat(20, 64, rng), w = random_mat(10, 64, rng);
  std::vector<float> bias(10, 0.5f);
  const Bf16Weight packed = bf16_pack(w.data(), 10, 64);
  LinearParams p{w.data(), bias.data(), 10, 64, &packed};
  Mat expected(20, 10);
  bf16_linear(x.data(), 20, packed, expected.data());
  expected.array() += 0.5f;
  EXPECT_EQ(linear(x, p), expected);
  p.bf16 = nullptr;  // fp32: differs in the last bits
  EXPECT_NE(linear(x, p), expected);
  EXPECT_TRUE(linear(x, p).isApprox(expected, 1e-2));
}

TEST(Bf16Packing, NeedsADepthThatFillsTiles) {
  EXPECT_TRUE(bf16_packable(3, 32));
  EXPECT_TRUE(bf16_packable(1089, 128));
  EXPECT_FALSE(bf16_packable(32, 7));  // the relation features: they stay fp32
  EXPECT_FALSE(bf16_packable(0, 32));
}

}  // namespace
}  // namespace ss
