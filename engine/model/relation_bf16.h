// The relation MLP (relu(W2 relu(W1 f + b1) + b2)) of many key pairs in one pass, when its second layer runs in bf16:
// sixteen pairs to a vector, so the result comes out as the attention kernels read it (one row per relation
// feature, keys across) with no products' set-up, bias and relu passes or transpose in between. Each output takes
// the same operations in the same order as `relation_embedding` with the AVX512-BF16 product (the shallow first
// layer's FMA chain, bias, relu, bf16 rounding, `vdpbf16ps` over the depth pairs in order, bias, relu), so a pair's
// bits do not depend on the pairs beside it (tests/unit/model/relation_bf16_test.cc).
#pragma once

#include "engine/model/linalg.h"

namespace ss {

// Whether relation_columns_bf16 runs these layers: fc2 packed in bf16, fc1 7 features wide (kRelationFeatures) into
// a multiple of 32 (at most 256) that fc2 reads, both with biases, and the CPU has AVX512-BF16.
bool relation_columns_bf16_fits(const LinearParams& fc1, const LinearParams& fc2);
// out (fc2.out x n, row-major: column j is pair j) from f (n x 7, row-major). Requires relation_columns_bf16_fits.
void relation_columns_bf16(const float* f, int n, const LinearParams& fc1, const LinearParams& fc2, float* out);

}  // namespace ss
