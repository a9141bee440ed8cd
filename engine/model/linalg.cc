#include "engine/model/linalg.h"

#include "engine/model/matmul_bf16.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>

namespace ss {

namespace {

#if defined(__AVX512F__)
// y = x W^T for inputs less than 8 wide (the relation MLP's 7 features) and outputs in whole vectors: each output a
// chain of FMAs in input order from zero, the order Eigen's GEMM takes below its 8-deep unrolling (the same bits in
// tests/unit/model/linalg_test.cc), without the GEMM's packing, which was most of its cost at this depth.
constexpr int kShallowDepth = 8;
bool shallow(const LinearParams& p) { return p.in < kShallowDepth && p.out % 16 == 0; }

void shallow_product(const Mat& x, const LinearParams& p, Mat& y) {
  const int in = p.in, out = p.out, rows = static_cast<int>(x.rows());
  y.resize(rows, out);
  for (int o0 = 0; o0 < out; o0 += 16) {
    __m512 w[kShallowDepth];  // w[k]: W[o0 .. o0 + 16)[k]
    for (int k = 0; k < in; ++k) {
      alignas(64) float col[16];
      for (int o = 0; o < 16; ++o) col[o] = p.weight[static_cast<size_t>(o0 + o) * in + k];
      w[k] = _mm512_load_ps(col);
    }
    for (int i = 0; i < rows; ++i) {
      const float* xi = x.data() + static_cast<size_t>(i) * in;
      __m512 acc = _mm512_setzero_ps();
      for (int k = 0; k < in; ++k) acc = _mm512_fmadd_ps(_mm512_set1_ps(xi[k]), w[k], acc);
      _mm512_storeu_ps(y.data() + static_cast<size_t>(i) * out + o0, acc);
    }
  }
}
#else
bool shallow(const LinearParams&) { return false; }
void shallow_product(const Mat&, const LinearParams&, Mat&) {}
#endif

}  // namespace

Mat linear(const Mat& x, const LinearParams& p) {
  Mat y;
  if (p.bf16) {
    y.resize(x.rows(), p.out);
    bf16_linear(x.data(), static_cast<int>(x.rows()), *p.bf16, y.data());
  } else if (shallow(p)) {
    shallow_product(x, p, y);
  } else {
    y = x * p.w().transpose();
  }
  if (p.bias) y.rowwise() += VecMap(p.bias, p.out);
  return y;
}

Mat layer_norm_plain(const Mat& x) {
  Mat y(x.rows(), x.cols());
  for (Eigen::Index r = 0; r < x.rows(); ++r) {
    const float mean = x.row(r).mean();
    const float var = (x.row(r).array() - mean).square().mean();
    y.row(r) = (x.row(r).array() - mean) / std::sqrt(var + kLayerNormEps);
  }
  return y;
}

Mat layer_norm(const Mat& x, const NormParams& p) {
  Mat y = layer_norm_plain(x);
  y.array().rowwise() *= VecMap(p.weight, p.dim).array();
  y.rowwise() += VecMap(p.bias, p.dim);
  return y;
}

void relu_inplace(Mat& x) { x = x.cwiseMax(0.0f); }

void softmax_inplace(float* v, int n) {
  if (n <= 0) return;
  const float m = *std::max_element(v, v + n);
  float sum = 0;
  for (int i = 0; i < n; ++i) sum += (v[i] = std::exp(v[i] - m));
  for (int i = 0; i < n; ++i) v[i] /= sum;
}

void enable_flush_to_zero() { _mm_setcsr(_mm_getcsr() | 0x8040); }

}  // namespace ss
