// The register-blocked attention kernels against their plain forms, for the shapes of both configurations and a
// shape only the plain forms serve, with key counts around the vector width.
#include "engine/model/attention_kernels.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>
#include <vector>

namespace ss {
namespace {

struct Case {
  AttentionShape shape;
  int m;
};

std::vector<float> random_floats(size_t n, std::mt19937& rng) {
  std::normal_distribution<float> dist(0, 1);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

void expect_near(const std::vector<float>& a, const std::vector<float>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size());
  float worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  EXPECT_LT(worst, 1e-4f) << what;
}

class KernelTest : public ::testing::TestWithParam<Case> {};

TEST_P(KernelTest, FastFormsEqualPlainForms) {
  const auto [s, m] = GetParam();
  std::mt19937 rng(7 + m);
  const int rows = 3 * m + 5;  // keys are scattered rows of a larger matrix, some repeated
  const auto k = random_floats(static_cast<size_t>(rows) * s.d(), rng);
  const auto v = random_floats(static_cast<size_t>(rows) * s.d(), rng);
  const auto q = random_floats(s.d(), rng);
  const auto u = random_floats(static_cast<size_t>(s.heads) * s.r, rng);
  const auto rel = random_floats(static_cast<size_t>(m) * s.r, rng);
  const auto a = random_floats(static_cast<size_t>(s.heads) * m, rng);
  std::vector<int> keys(m);
  for (int j = 0; j < m; ++j) keys[j] = (j * 7 + j / 3) % rows;

  std::vector<float> fast(static_cast<size_t>(s.heads) * m), plain(fast.size());
  kernel_key_scores(s, q.data(), k.data(), keys.data(), m, fast.data());
  kernel_key_scores_plain(s, q.data(), k.data(), keys.data(), m, plain.data());
  expect_near(fast, plain, "key scores");

  // The relation kernels on the first m - m / 3 keys (a query's keys with relation columns come first: r x mp,
  // key-major), score rows m apart.
  const int mp = m - m / 3;
  kernel_relation_scores(s, u.data(), rel.data(), mp, fast.data(), m);
  kernel_relation_scores_plain(s, u.data(), rel.data(), mp, plain.data(), m);
  expect_near(fast, plain, "relation scores (added to the key scores)");

  // Half-float storage: the fast forms against the plain ones on the same halves, and against the float kernels on
  // the rounded rows.
  std::vector<uint16_t> kh(k.size()), vh(v.size());
  floats_to_halves(k.data(), static_cast<int>(k.size()), kh.data());
  floats_to_halves(v.data(), static_cast<int>(v.size()), vh.data());
  std::vector<float> k_rounded(k.size()), v_rounded(v.size());
  halves_to_floats(kh.data(), static_cast<int>(kh.size()), k_rounded.data());
  halves_to_floats(vh.data(), static_cast<int>(vh.size()), v_rounded.data());
  {
    std::vector<float> half_fast(fast.size()), half_plain(fast.size()), rounded(fast.size());
    kernel_key_scores_f16(s, q.data(), kh.data(), keys.data(), m, half_fast.data());
    kernel_key_scores_f16_plain(s, q.data(), kh.data(), keys.data(), m, half_plain.data());
    kernel_key_scores_plain(s, q.data(), k_rounded.data(), keys.data(), m, rounded.data());
    expect_near(half_fast, half_plain, "key scores from halves");
    expect_near(half_fast, rounded, "key scores from halves vs rounded floats");
    std::vector<float> o_fast(s.d(), 0.5f), o_plain(s.d(), 0.5f), o_rounded(s.d(), 0.5f);
    kernel_weighted_values_f16(s, a.data(), vh.data(), keys.data(), m, o_fast.data());
    kernel_weighted_values_f16_plain(s, a.data(), vh.data(), keys.data(), m, o_plain.data());
    kernel_weighted_values_plain(s, a.data(), v_rounded.data(), keys.data(), m, o_rounded.data());
    expect_near(o_fast, o_plain, "weighted values from halves");
    expect_near(o_fast, o_rounded, "weighted values from halves vs rounded floats");
  }

  std::vector<float> out_fast(s.d(), 0.5f), out_plain(s.d(), 0.5f);  // the values are added to what is there
  kernel_weighted_values(s, a.data(), v.data(), keys.data(), m, out_fast.data());
  kernel_weighted_values_plain(s, a.data(), v.data(), keys.data(), m, out_plain.data());
  expect_near(out_fast, out_plain, "weighted values");

  std::vector<float> rel_fast(static_cast<size_t>(s.heads) * s.r, 9.0f), rel_plain(rel_fast.size(), -9.0f);
  kernel_weighted_relation(s, a.data(), rel.data(), mp, m, rel_fast.data());
  kernel_weighted_relation_plain(s, a.data(), rel.data(), mp, m, rel_plain.data());
  expect_near(rel_fast, rel_plain, "weighted relation (overwrites its output)");

  if (m == 0) return;
  // Softmax of the scores' rows, rows m + 3 apart (the padding must stay untouched), scores spread wide enough
  // that exp underflows for some keys.
  const int stride = m + 3;
  std::vector<float> soft_fast(static_cast<size_t>(s.heads) * stride, 42.0f);
  for (int h = 0; h < s.heads; ++h)
    for (int j = 0; j < m; ++j) soft_fast[h * stride + j] = 30.0f * a[h * m + j];
  std::vector<float> soft_plain = soft_fast;
  kernel_softmax_rows(soft_fast.data(), s.heads, m, stride, 0.125f);
  kernel_softmax_rows_plain(soft_plain.data(), s.heads, m, stride, 0.125f);
  expect_near(soft_fast, soft_plain, "softmax rows");
  for (int h = 0; h < s.heads; ++h) {
    float sum = 0;
    for (int j = 0; j < m; ++j) sum += soft_fast[h * stride + j];
    EXPECT_NEAR(sum, 1.0f, 1e-5f) << "head " << h;
    for (int j = m; j < stride; ++j) EXPECT_EQ(soft_fast[h * stride + j], 42.0f) << "padding of head " << h;
  }
  // Unnormalised, with each row's 1 / sum returned: times it, the same weights (both forms).
  for (const bool fast : {true, false}) {
    std::vector<float> raw(static_cast<size_t>(s.heads) * stride, 42.0f), inv(s.heads, -1.0f);
    for (int h = 0; h < s.heads; ++h)
      for (int j = 0; j < m; ++j) raw[h * stride + j] = 30.0f * a[h * m + j];
    if (fast) kernel_softmax_rows(raw.data(), s.heads, m, stride, 0.125f, inv.data());
    else kernel_softmax_rows_plain(raw.data(), s.heads, m, stride, 0.125f, inv.data());
    const std::vector<float>& normalised = fast ? soft_fast : soft_plain;
    for (int h = 0; h < s.heads; ++h) {
      float top = 0;
      for (int j = 0; j < m; ++j) {
        top = std::max(top, raw[h * stride + j]);
        EXPECT_NEAR(raw[h * stride + j] * inv[h], normalised[h * stride + j], 1e-6f) << "head " << h << " key " << j;
      }
      EXPECT_EQ(top, 1.0f) << "the largest weight is exp(0), head " << h;
      for (int j = m; j < stride; ++j) EXPECT_EQ(raw[h * stride + j], 42.0f) << "padding of head " << h;
    }
  }
}

// The vector conversion (F16C where the build has it) equals the software one bit for bit, rounds to nearest even,
// keeps subnormals, and saturates instead of overflowing to infinity.
TEST(HalfFloats, ConversionRoundsToNearestAndSaturates) {
  std::mt19937 rng(3);
  std::vector<float> x = random_floats(1000, rng);
  for (float& f : x) f *= 100.0f;
  const std::vector<float> special = {0.0f, -0.0f, 1.0f, -2.5f, 65504.0f, 70000.0f, -1e9f, 6.0e-8f, 3.0e-5f,
                                      -1.0e-6f, 1.0f + 1.0f / 2048, 1.0f + 3.0f / 2048, 1e-12f};
  x.insert(x.end(), special.begin(), special.end());
  const int n = static_cast<int>(x.size());
  std::vector<uint16_t> fast(n);
  floats_to_halves(x.data(), n, fast.data());
  std::vector<float> back(n);
  halves_to_floats(fast.data(), n, back.data());
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(fast[i], float_to_half(x[i])) << x[i];
    EXPECT_EQ(back[i], half_to_float(fast[i])) << x[i];
    const float clamped = std::clamp(x[i], -65504.0f, 65504.0f);
    // Half precision: 11 significant bits for normal values (relative error <= 2^-11), 2^-24 absolute below 2^-14.
    EXPECT_LE(std::abs(back[i] - clamped), std::max(std::abs(clamped) / 2048.0f, 3.0e-8f)) << x[i];
  }
  EXPECT_EQ(half_to_float(float_to_half(1.0f + 1.0f / 2048)), 1.0f);                 // a tie: to even
  EXPECT_EQ(half_to_float(float_to_half(1.0f + 3.0f / 2048)), 1.0f + 4.0f / 2048);   // a tie: to even
  EXPECT_EQ(half_to_float(float_to_half(70000.0f)), 65504.0f);
  EXPECT_EQ(half_to_float(float_to_half(-1e9f)), -65504.0f);
  EXPECT_EQ(float_to_half(-0.0f), 0x8000);
}

// The fast softmax's exp against std::exp, relatively: every weight from 1 down to 1e-38 within 1e-6 of the plain
// form's, exp's underflow to exactly 0 where the plain form's is 0, and a -inf score weighing nothing.
TEST(Kernels, SoftmaxWeightsMatchStdExpRelatively) {
  const int m = 2049;
  std::vector<float> fast(m);
  for (int j = 0; j < m; ++j) fast[j] = -110.0f * static_cast<float>(j) / (m - 2);  // 0 down to -110 (underflow)
  fast[m - 1] = -std::numeric_limits<float>::infinity();
  std::vector<float> plain = fast;
  kernel_softmax_rows(fast.data(), 1, m, m, 1.0f);
  kernel_softmax_rows_plain(plain.data(), 1, m, m, 1.0f);
  for (int j = 0; j < m; ++j) {
    if (plain[j] > 1e-38f) EXPECT_NEAR(fast[j] / plain[j], 1.0f, 1e-6f) << "score " << j;
    else EXPECT_LE(fast[j], 2e-38f) << "score " << j;
  }
  EXPECT_EQ(fast[m - 1], 0.0f);
}

// The blocked transpose moves every element where the plain one does: shapes on both sides of a block's edges.
TEST(Kernels, TransposeEqualsThePlainTranspose) {
  std::mt19937 rng(3);
  for (int rows : {0, 1, 15, 16, 17, 45, 300})
    for (int cols : {1, 7, 16, 17, 32, 33}) {
      const std::vector<float> src = random_floats(static_cast<size_t>(rows) * cols, rng);
      std::vector<float> fast(src.size(), -1.0f), plain(src.size(), -2.0f);
      kernel_transpose(src.data(), rows, cols, fast.data());
      kernel_transpose_plain(src.data(), rows, cols, plain.data());
      EXPECT_EQ(fast, plain) << rows << " x " << cols;
    }
}

INSTANTIATE_TEST_SUITE_P(Shapes, KernelTest,
                         ::testing::Values(Case{{4, 32, 32}, 1}, Case{{4, 32, 32}, 15}, Case{{4, 32, 32}, 16},
                                           Case{{4, 32, 32}, 17}, Case{{4, 32, 32}, 250}, Case{{4, 16, 32}, 33},
                                           Case{{8, 16, 32}, 40}, Case{{4, 32, 16}, 70}, Case{{2, 24, 8}, 20},
                                           Case{{4, 32, 32}, 0}));

}  // namespace
}  // namespace ss
