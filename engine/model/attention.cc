#include "engine/model/attention.h"

#include <cmath>

namespace ss {

RelationFeatures relation_features(const Anchor& q, const Anchor& k) {
  RelationFeatures f{};
  f[5] = static_cast<float>(q.step - k.step) / 5.0f;
  if (!q.has_pose || !k.has_pose) return f;
  const Vec2 local = to_local(q.pose, {k.pose.x, k.pose.y});
  const double dpsi = k.pose.heading - q.pose.heading;
  f[0] = static_cast<float>(local.x / 10.0);
  f[1] = static_cast<float>(local.y / 10.0);
  f[2] = static_cast<float>(norm(local) / 10.0);
  f[3] = static_cast<float>(std::sin(dpsi));
  f[4] = static_cast<float>(std::cos(dpsi));
  f[6] = 1.0f;
  return f;
}

Mat relation_embedding(const Mat& features, const RelationParams& p) {
  Mat h = linear(features, p.fc1);
  relu_inplace(h);
  h = linear(h, p.fc2);
  relu_inplace(h);
  return h;
}

Mat relative_attention(const Mat& x, const AttentionParams& p, int heads, const MatMap& k, const MatMap& v,
                       std::span<const QueryKeys* const> query_keys) {
  const int n = static_cast<int>(x.rows());
  const int d = static_cast<int>(x.cols());
  const int dh = d / heads;
  const int r = p.rel_key.in;
  const float scale = 1.0f / std::sqrt(static_cast<float>(dh));
  const Mat q = linear(x, p.query);
  const Mat q_rel = linear(x, p.rel_query);
  const MatMap w_rk = p.rel_key.w();    // [d, r]
  const MatMap w_rv = p.rel_value.w();  // [d, r]

  Mat o(n, d);
  Mat scores, head_k, head_v;
  Vec u, weighted_h;
  for (int i = 0; i < n; ++i) {
    const QueryKeys& qk = *query_keys[i];
    const int m = static_cast<int>(qk.keys.size());
    for (int h = 0; h < heads; ++h) {
      const int c0 = h * dh;
      auto o_h = o.row(i).segment(c0, dh);
      if (m == 0) {
        o_h = VecMap(p.rel_value.bias + c0, dh);
        continue;
      }
      u = q_rel.row(i).segment(c0, dh) * w_rk.middleRows(c0, dh);  // 1 x r
      Vec s(m);
      for (int j = 0; j < m; ++j)
        s[j] = (q.row(i).segment(c0, dh).dot(k.row(qk.keys[j]).segment(c0, dh)) + u.dot(qk.relation.row(j))) * scale;
      softmax_inplace(s.data(), m);
      o_h.setZero();
      for (int j = 0; j < m; ++j) o_h.noalias() += s[j] * v.row(qk.keys[j]).segment(c0, dh);
      weighted_h = s * qk.relation;  // 1 x r
      o_h.noalias() += weighted_h * w_rv.middleRows(c0, dh).transpose();
      o_h += VecMap(p.rel_value.bias + c0, dh);
    }
  }
  (void)r;
  return linear(o, p.output);
}

}  // namespace ss
