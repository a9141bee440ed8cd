#include "training/sparse_attention.h"

#include <ATen/Parallel.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace ss::train {
namespace {

struct Shape {
  int64_t n, m, d, heads, dh, r;
  float scale;
};

inline float dot(const float* a, const float* b, int64_t n) {
  float s = 0;
  for (int64_t i = 0; i < n; ++i) s += a[i] * b[i];
  return s;
}

inline void axpy(float a, const float* x, float* y, int64_t n) {
  for (int64_t i = 0; i < n; ++i) y[i] += a * x[i];
}

class SparseAttention : public torch::autograd::Function<SparseAttention> {
 public:
  static torch::autograd::variable_list forward(torch::autograd::AutogradContext* ctx, torch::Tensor q,
                                                torch::Tensor u, torch::Tensor k, torch::Tensor v, torch::Tensor h,
                                                torch::Tensor offsets, torch::Tensor keys, int64_t heads) {
    q = q.contiguous(), u = u.contiguous(), k = k.contiguous(), v = v.contiguous(), h = h.contiguous();
    const Shape s = shape_of(q, k, h, heads);
    auto out = torch::zeros({s.n, s.d}, q.options());
    auto hbar = torch::zeros({s.n, s.heads * s.r}, q.options());
    auto weights = torch::empty({keys.size(0), s.heads}, q.options());  // a_e^h, kept for the backward pass
    const int64_t* off = offsets.data_ptr<int64_t>();
    const int64_t* key = keys.data_ptr<int64_t>();
    const float *qp = q.data_ptr<float>(), *up = u.data_ptr<float>(), *kp = k.data_ptr<float>(),
                *vp = v.data_ptr<float>(), *hp = h.data_ptr<float>();
    float *op = out.data_ptr<float>(), *hb = hbar.data_ptr<float>(), *ap = weights.data_ptr<float>();
    at::parallel_for(0, s.n, 16, [&](int64_t begin, int64_t end) {
      for (int64_t i = begin; i < end; ++i) {
        const int64_t e0 = off[i], e1 = off[i + 1];
        if (e0 == e1) continue;
        for (int64_t hd = 0; hd < s.heads; ++hd) {
          const float* qi = qp + i * s.d + hd * s.dh;
          const float* ui = up + (i * s.heads + hd) * s.r;
          float mx = -INFINITY;
          for (int64_t e = e0; e < e1; ++e) {
            const float sc = s.scale * (dot(qi, kp + key[e] * s.d + hd * s.dh, s.dh) + dot(ui, hp + e * s.r, s.r));
            ap[e * s.heads + hd] = sc;
            mx = std::max(mx, sc);
          }
          float sum = 0;
          for (int64_t e = e0; e < e1; ++e) sum += (ap[e * s.heads + hd] = std::exp(ap[e * s.heads + hd] - mx));
          const float inv = 1.0f / sum;
          float* oi = op + i * s.d + hd * s.dh;
          float* hi = hb + (i * s.heads + hd) * s.r;
          for (int64_t e = e0; e < e1; ++e) {
            const float a = ap[e * s.heads + hd] *= inv;
            axpy(a, vp + key[e] * s.d + hd * s.dh, oi, s.dh);
            axpy(a, hp + e * s.r, hi, s.r);
          }
        }
      }
    });
    ctx->save_for_backward({q, u, k, v, h, offsets, keys, weights});
    ctx->saved_data["heads"] = heads;
    return {out, hbar};
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grads) {
    const auto saved = ctx->get_saved_variables();
    const torch::Tensor &q = saved[0], &u = saved[1], &k = saved[2], &v = saved[3], &h = saved[4],
                        &offsets = saved[5], &keys = saved[6], &weights = saved[7];
    const Shape s = shape_of(q, k, h, ctx->saved_data["heads"].toInt());
    const torch::Tensor go = grads[0].defined() ? grads[0].contiguous() : torch::zeros_like(q);
    const torch::Tensor ghb = grads[1].defined() ? grads[1].contiguous() : torch::zeros_like(u);
    auto dq = torch::zeros_like(q), du = torch::zeros_like(u), dh = torch::zeros_like(h);
    const int threads = at::get_num_threads();
    // Keys and values are shared between queries: each thread adds into its own buffer, summed at the end.
    std::vector<torch::Tensor> dk(threads), dv(threads);
    for (int t = 0; t < threads; ++t) dk[t] = torch::zeros_like(k), dv[t] = torch::zeros_like(v);
    const int64_t* off = offsets.data_ptr<int64_t>();
    const int64_t* key = keys.data_ptr<int64_t>();
    const float *qp = q.data_ptr<float>(), *up = u.data_ptr<float>(), *kp = k.data_ptr<float>(),
                *vp = v.data_ptr<float>(), *hp = h.data_ptr<float>(), *ap = weights.data_ptr<float>(),
                *gop = go.data_ptr<float>(), *ghp = ghb.data_ptr<float>();
    float *dqp = dq.data_ptr<float>(), *dup = du.data_ptr<float>(), *dhp = dh.data_ptr<float>();
    const int64_t chunk = std::max<int64_t>(1, (s.n + threads - 1) / threads);
    at::parallel_for(0, threads, 1, [&](int64_t tb, int64_t te) {
      for (int64_t t = tb; t < te; ++t) {
        float* dkp = dk[t].data_ptr<float>();
        float* dvp = dv[t].data_ptr<float>();
        std::vector<float> ds;
        for (int64_t i = t * chunk; i < std::min(s.n, (t + 1) * chunk); ++i) {
          const int64_t e0 = off[i], e1 = off[i + 1];
          ds.resize(e1 - e0);
          for (int64_t hd = 0; hd < s.heads; ++hd) {
            const float* qi = qp + i * s.d + hd * s.dh;
            const float* ui = up + (i * s.heads + hd) * s.r;
            const float* goi = gop + i * s.d + hd * s.dh;
            const float* ghi = ghp + (i * s.heads + hd) * s.r;
            float c = 0;
            for (int64_t e = e0; e < e1; ++e) {
              const float da = dot(goi, vp + key[e] * s.d + hd * s.dh, s.dh) + dot(ghi, hp + e * s.r, s.r);
              ds[e - e0] = da;
              c += ap[e * s.heads + hd] * da;
            }
            float* dqi = dqp + i * s.d + hd * s.dh;
            float* dui = dup + (i * s.heads + hd) * s.r;
            for (int64_t e = e0; e < e1; ++e) {
              const float a = ap[e * s.heads + hd];
              const float g = a * (ds[e - e0] - c) * s.scale;  // d loss / d (q.k + u.h)
              const int64_t j = key[e];
              axpy(g, kp + j * s.d + hd * s.dh, dqi, s.dh);
              axpy(g, hp + e * s.r, dui, s.r);
              axpy(g, qi, dkp + j * s.d + hd * s.dh, s.dh);
              axpy(a, goi, dvp + j * s.d + hd * s.dh, s.dh);
              float* dhe = dhp + e * s.r;
              axpy(g, ui, dhe, s.r);
              axpy(a, ghi, dhe, s.r);
            }
          }
        }
      }
    });
    torch::Tensor dk_sum = dk[0], dv_sum = dv[0];
    for (int t = 1; t < threads; ++t) dk_sum += dk[t], dv_sum += dv[t];
    return {dq, du, dk_sum, dv_sum, dh, torch::Tensor(), torch::Tensor(), torch::Tensor()};
  }

 private:
  static Shape shape_of(const torch::Tensor& q, const torch::Tensor& k, const torch::Tensor& h, int64_t heads) {
    const int64_t d = q.size(1);
    return {q.size(0), k.size(0), d, heads, d / heads, h.size(1), 1.0f / std::sqrt(static_cast<float>(d / heads))};
  }
};

}  // namespace

std::pair<torch::Tensor, torch::Tensor> sparse_attention(const torch::Tensor& q, const torch::Tensor& u,
                                                         const torch::Tensor& k, const torch::Tensor& v,
                                                         const torch::Tensor& h, const SparseKeys& keys, int heads) {
  TORCH_CHECK(q.dim() == 2 && k.dim() == 2 && v.sizes() == k.sizes() && q.size(1) == k.size(1) && q.size(1) % heads == 0,
              "sparse_attention: q [n, d], k and v [m, d] with d divisible by heads");
  TORCH_CHECK(u.size(0) == q.size(0) && u.size(1) == heads * h.size(1), "sparse_attention: u must be [n, heads * r]");
  TORCH_CHECK(keys.offsets.numel() == q.size(0) + 1 && keys.keys.numel() == h.size(0),
              "sparse_attention: offsets [n + 1] and one relation row per key");
  auto out = SparseAttention::apply(q, u, k, v, h, keys.offsets, keys.keys, heads);
  return {out[0], out[1]};
}

}  // namespace ss::train
