// The hand-written sparse attention against the same math in plain torch operations (per-pair gathers and a
// per-query softmax), forward and every gradient, on random key lists with empty and single-key queries.
#include "training/sparse_attention.h"

#include <gtest/gtest.h>

namespace ss::train {
namespace {

std::pair<torch::Tensor, torch::Tensor> reference(const torch::Tensor& q, const torch::Tensor& u, const torch::Tensor& k,
                                                  const torch::Tensor& v, const torch::Tensor& h,
                                                  const std::vector<std::vector<int64_t>>& lists, int heads) {
  const int64_t d = q.size(1), dh = d / heads, r = h.size(1);
  std::vector<torch::Tensor> outs, hbars;
  int64_t e = 0;
  for (size_t i = 0; i < lists.size(); ++i) {
    const int64_t m = lists[i].size();
    if (m == 0) {
      outs.push_back(torch::zeros({d}));
      hbars.push_back(torch::zeros({heads * r}));
      continue;
    }
    const torch::Tensor idx = torch::tensor(lists[i]);
    const torch::Tensor kk = k.index_select(0, idx).view({m, heads, dh});
    const torch::Tensor vv = v.index_select(0, idx).view({m, heads, dh});
    const torch::Tensor hh = h.slice(0, e, e + m);  // [m, r]
    const torch::Tensor s = ((kk * q[i].view({1, heads, dh})).sum(-1) + torch::matmul(hh, u[i].view({heads, r}).t())) /
                            std::sqrt(static_cast<double>(dh));  // [m, heads]
    const torch::Tensor a = torch::softmax(s, 0);
    outs.push_back((a.unsqueeze(-1) * vv).sum(0).reshape({d}));
    hbars.push_back(torch::matmul(a.t(), hh).reshape({heads * r}));
    e += m;
  }
  return {torch::stack(outs), torch::stack(hbars)};
}

TEST(SparseAttention, MatchesPlainTorchForwardAndBackward) {
  torch::manual_seed(11);
  const int heads = 4, n = 9, m = 13, d = 16, r = 6;
  std::vector<std::vector<int64_t>> lists = {{0, 3, 5}, {}, {12}, {1, 2, 3, 4, 5, 6, 7}, {0, 12}, {4}, {}, {2, 9, 11}, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}};
  std::vector<int64_t> offsets{0}, keys;
  for (const auto& l : lists) {
    keys.insert(keys.end(), l.begin(), l.end());
    offsets.push_back(keys.size());
  }
  const int64_t e = keys.size();
  auto param = [](std::vector<int64_t> shape) { return (torch::randn(shape) * 0.7).set_requires_grad(true); };
  const torch::Tensor q = param({n, d}), u = param({n, heads * r}), k = param({m, d}), v = param({m, d}), h = param({e, r});
  const torch::Tensor w1 = torch::randn({n, d}), w2 = torch::randn({n, heads * r});

  auto [out, hbar] = sparse_attention(q, u, k, v, h, {torch::tensor(offsets), torch::tensor(keys)}, heads);
  ((out * w1).sum() + (hbar * w2).sum()).backward();
  const std::vector<torch::Tensor> grads = {q.grad().clone(), u.grad().clone(), k.grad().clone(), v.grad().clone(),
                                            h.grad().clone()};
  for (const auto& t : {q, u, k, v, h}) const_cast<torch::Tensor&>(t).mutable_grad().zero_();

  auto [ref_out, ref_hbar] = reference(q, u, k, v, h, lists, heads);
  ((ref_out * w1).sum() + (ref_hbar * w2).sum()).backward();
  EXPECT_LT((out - ref_out).abs().max().item<float>(), 1e-5);
  EXPECT_LT((hbar - ref_hbar).abs().max().item<float>(), 1e-5);
  const char* names[] = {"q", "u", "k", "v", "h"};
  const std::vector<torch::Tensor> ref_grads = {q.grad(), u.grad(), k.grad(), v.grad(), h.grad()};
  for (int i = 0; i < 5; ++i)
    EXPECT_LT((grads[i] - ref_grads[i]).abs().max().item<float>(), 1e-4) << "gradient of " << names[i];
  // The empty queries give zeros.
  EXPECT_EQ(out[1].abs().sum().item<float>(), 0.0f);
}

TEST(SparseAttention, RejectsMismatchedShapes) {
  const torch::Tensor q = torch::zeros({2, 8}), u = torch::zeros({2, 8}), k = torch::zeros({3, 8}), h = torch::zeros({1, 2});
  EXPECT_THROW(sparse_attention(q, u, k, k, h, {torch::tensor(std::vector<int64_t>{0, 1}), torch::tensor(std::vector<int64_t>{0})}, 4),
               c10::Error);
}

}  // namespace
}  // namespace ss::train
