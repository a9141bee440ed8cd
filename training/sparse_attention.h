// The engine's sparse relative attention (engine/model/attention.h) as a differentiable torch operation, with its
// forward and backward written out: each query reads its own keys (CSR lists), so no per-pair tensor of width d is
// ever made (gathering k and v per pair would move ~100 MB per layer and dominate a step).
//   s_e^h   = scale (q_i^h . k_j^h + u_i^h . h_e)       for each key e = (i, j) of query i and head h
//   a       = softmax over query i's keys, per head
//   out_i^h = sum_e a_e^h v_j^h,   hbar_i^h = sum_e a_e^h h_e
// u_i^h = W_rk^h^T q'_i^h is the folded relation query and h_e the pair's relation embedding (shared by the layers);
// the caller adds W_rv^h hbar_i^h + b_rv and the output projection.
#pragma once

#include <torch/torch.h>

namespace ss::train {

struct SparseKeys {
  torch::Tensor offsets;  // int64 [n + 1]: query i reads keys[offsets[i] .. offsets[i + 1])
  torch::Tensor keys;     // int64 [E]: rows of k and v
};

// q [n, d], u [n, heads * r], k and v [m, d], h [E, r]. Returns {out [n, d], hbar [n, heads * r]}. A query without
// keys gets zeros.
std::pair<torch::Tensor, torch::Tensor> sparse_attention(const torch::Tensor& q, const torch::Tensor& u,
                                                         const torch::Tensor& k, const torch::Tensor& v,
                                                         const torch::Tensor& h, const SparseKeys& keys, int heads);

}  // namespace ss::train
