// The few dense operations the model needs, on row-major float matrices (one token per row).
// Kept plain so the libtorch trainer can reproduce them exactly: Linear is y = x W^T + b with W [out, in];
// LayerNorm uses eps 1e-5 and the biased variance, as torch.nn.LayerNorm does.
#pragma once

#include <Eigen/Core>

namespace ss {

struct Bf16Weight;

using Mat = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Vec = Eigen::Matrix<float, 1, Eigen::Dynamic, Eigen::RowMajor>;
using MatMap = Eigen::Map<const Mat>;
using VecMap = Eigen::Map<const Vec>;

inline constexpr float kLayerNormEps = 1e-5f;

struct LinearParams {
  const float* weight = nullptr;  // [out, in]
  const float* bias = nullptr;    // [out], or null
  int out = 0, in = 0;
  const Bf16Weight* bf16 = nullptr;  // W in bf16 tiles when the model runs its products in bf16, else null

  MatMap w() const { return MatMap(weight, out, in); }
};

struct NormParams {
  const float* weight = nullptr;
  const float* bias = nullptr;
  int dim = 0;
};

// y = x W^T + b (in bf16 when p.bf16 is set: engine/model/matmul_bf16.h)
Mat linear(const Mat& x, const LinearParams& p);
// Row-wise LayerNorm with affine parameters.
Mat layer_norm(const Mat& x, const NormParams& p);
// Row-wise LayerNorm without affine parameters.
Mat layer_norm_plain(const Mat& x);
void relu_inplace(Mat& x);
// Softmax of a vector in place, with the max subtracted first.
void softmax_inplace(float* v, int n);

// Sets flush-to-zero and denormals-are-zero for the calling thread: tiny values otherwise slow x86 math by 2-7x.
void enable_flush_to_zero();

}  // namespace ss
