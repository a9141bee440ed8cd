#include "engine/model/attention.h"

#include <cmath>
#include <map>

namespace ss {

RelationFeatures relation_features(const Anchor& q, const Anchor& k) {
  RelationFeatures f{};
  f[5] = static_cast<float>(q.step - k.step) / 5.0f;
  if (!q.has_pose || !k.has_pose) return f;
  // The key's offset in the query's frame, and the heading difference, from the cached cosines and sines.
  const double dx = k.pose.x - q.pose.x, dy = k.pose.y - q.pose.y;
  const double lx = q.cos_h * dx + q.sin_h * dy, ly = -q.sin_h * dx + q.cos_h * dy;
  f[0] = static_cast<float>(lx / 10.0);
  f[1] = static_cast<float>(ly / 10.0);
  f[2] = static_cast<float>(std::sqrt(lx * lx + ly * ly) / 10.0);
  f[3] = static_cast<float>(k.sin_h * q.cos_h - k.cos_h * q.sin_h);  // sin(psi_k - psi_q)
  f[4] = static_cast<float>(k.cos_h * q.cos_h + k.sin_h * q.sin_h);  // cos(psi_k - psi_q)
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

namespace {

// Softmax of each row in place (rows are contiguous, so exp vectorises).
void softmax_rows(Mat& s) {
  for (Eigen::Index i = 0; i < s.rows(); ++i) {
    auto row = s.row(i).array();
    row = (row - row.maxCoeff()).exp();
    row /= row.sum();
  }
}

}  // namespace

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
  // u_i^h = W_rk^h^T q'_i^h: the relation query of each head, n x (heads * r).
  Mat u(n, heads * r);
  for (int h = 0; h < heads; ++h)
    u.middleCols(h * r, r).noalias() = q_rel.middleCols(h * dh, dh) * w_rk.middleRows(h * dh, dh);

  // Queries reading the same key set go together.
  std::map<const QueryKeys*, std::vector<int>> groups;
  for (int i = 0; i < n; ++i) groups[query_keys[i]].push_back(i);

  Mat o(n, d);
  Mat kg, vg, s, weighted_h, og;
  for (const auto& [set, rows] : groups) {
    const int m = static_cast<int>(set->keys.size());
    const int g = static_cast<int>(rows.size());
    if (m == 0) {
      for (int i : rows)
        for (int h = 0; h < heads; ++h) o.row(i).segment(h * dh, dh) = VecMap(p.rel_value.bias + h * dh, dh);
      continue;
    }
    if (g <= 2) {
      // Few queries: read the key rows in place (a gather would copy every head's columns for one use each).
      Vec sc(m), rel(m), wh(r), acc(dh);
      for (int i : rows) {
        for (int h = 0; h < heads; ++h) {
          const auto qh = q.row(i).segment(h * dh, dh);
          for (int j = 0; j < m; ++j) sc[j] = qh.dot(k.row(set->keys[j]).segment(h * dh, dh));
          if (!set->uniform) sc.noalias() += u.row(i).segment(h * r, r) * set->relation.transpose();
          sc *= scale;
          sc = (sc.array() - sc.maxCoeff()).exp();
          sc /= sc.sum();
          acc.setZero();
          for (int j = 0; j < m; ++j) acc.noalias() += sc[j] * v.row(set->keys[j]).segment(h * dh, dh);
          if (set->uniform)
            wh = set->relation.row(0);
          else
            wh.noalias() = sc * set->relation;
          acc.noalias() += wh * w_rv.middleRows(h * dh, dh).transpose();
          o.row(i).segment(h * dh, dh) = acc + VecMap(p.rel_value.bias + h * dh, dh);
        }
      }
      continue;
    }
    // Keys 0..m-1 of k in order (a whole map): read in place; otherwise gather the rows once for the group.
    const bool identity = m == k.rows() && set->keys.front() == 0 && set->keys.back() == m - 1;
    if (!identity) {
      kg = k(set->keys, Eigen::placeholders::all);
      vg = v(set->keys, Eigen::placeholders::all);
    }
    const MatMap kk = identity ? k : MatMap(kg.data(), m, d);
    const MatMap vv = identity ? v : MatMap(vg.data(), m, d);
    for (int h = 0; h < heads; ++h) {
      // Scores, queries down and keys across: g x m.
      s.noalias() = q(rows, Eigen::seqN(h * dh, dh)) * kk.middleCols(h * dh, dh).transpose();
      if (!set->uniform) s.noalias() += u(rows, Eigen::seqN(h * r, r)) * set->relation.transpose();
      s *= scale;
      softmax_rows(s);
      og.noalias() = s * vv.middleCols(h * dh, dh);  // g x dh
      if (set->uniform)
        weighted_h = set->relation.row(0).replicate(g, 1);  // the weights sum to one
      else
        weighted_h.noalias() = s * set->relation;  // g x r
      og.noalias() += weighted_h * w_rv.middleRows(h * dh, dh).transpose();
      og.rowwise() += VecMap(p.rel_value.bias + h * dh, dh);
      for (int c = 0; c < g; ++c) o.row(rows[c]).segment(h * dh, dh) = og.row(c);
    }
  }
  return linear(o, p.output);
}

}  // namespace ss
