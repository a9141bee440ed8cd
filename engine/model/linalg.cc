#include "engine/model/linalg.h"

#include "engine/model/matmul_bf16.h"

#include <xmmintrin.h>

#include <algorithm>
#include <cmath>

namespace ss {

Mat linear(const Mat& x, const LinearParams& p) {
  Mat y;
  if (p.bf16) {
    y.resize(x.rows(), p.out);
    bf16_linear(x.data(), static_cast<int>(x.rows()), *p.bf16, y.data());
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
