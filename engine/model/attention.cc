#include "engine/model/attention.h"

#include <algorithm>
#include <cmath>

#include "engine/model/attention_kernels.h"
#include "engine/model/matmul_bf16.h"
#include "engine/model/relation_bf16.h"

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

Mat relation_columns(const Mat& features, const RelationParams& p) {
  const Mat h = relation_embedding(features, p);
  Mat columns(h.cols(), h.rows());
  kernel_transpose(h.data(), static_cast<int>(h.rows()), static_cast<int>(h.cols()), columns.data());
  return columns;
}

void set_relation_columns(std::span<QueryKeys* const> sets, std::span<const std::vector<float>> features,
                          const RelationParams& p) {
  // Each set alone, as a set's columns must not depend on the call it is made in: a restored session rebuilds its
  // cache's map key sets in other calls than the first run made them in, and must continue bit for bit. With the
  // second layer in bf16, the fused pass (relation_bf16.h) gives the AVX512-BF16 product path's bits without its
  // set-up, passes and transpose, 1.3-1.5x as fast (bench/relation_bench; a busy server builds 40,000 columns per
  // decode call).
  const bool fused = relation_columns_bf16_fits(p.fc1, p.fc2);
  for (size_t i = 0; i < sets.size(); ++i) {
    const int n = static_cast<int>(features[i].size()) / kRelationFeatures;
    if (fused) {
      sets[i]->relation.resize(p.fc2.out, n);
      relation_columns_bf16(features[i].data(), n, p.fc1, p.fc2, sets[i]->relation.data());
    } else {
      sets[i]->relation = relation_columns(MatMap(features[i].data(), n, kRelationFeatures), p);
    }
  }
}

Mat relation_by_step(const RelationParams& p, int steps) {
  Mat f = Mat::Zero(steps, kRelationFeatures);
  for (int dt = 0; dt < steps; ++dt) f(dt, 5) = static_cast<float>(dt) / 5.0f;  // as relation_features() writes it
  return relation_embedding(f, p);
}

namespace {

// The relation terms of the keys that share table rows, run by run. Scores: s[h][key] += u_h . table[row] (one dot
// product per head and table row, added over the run's keys). Weighted relation: rel[h] += sum_row (sum of the run's
// weights) table[row]. `s`, `a`: g x m per head as a row-major block of g rows.
struct TableTerms {
  Mat per_row;  // scratch: heads x table rows, or g x table rows

  void add_scores(const QueryKeys& set, const float* u, int heads, int r, float* s, int stride) {
    per_row.noalias() = MatMap(u, heads, r).lazyProduct(set.table->transpose());  // tiny: no GEMM set-up
    for (int h = 0; h < heads; ++h) {
      float* sh = s + h * stride + set.posed();
      for (const QueryKeys::TableRun& run : set.table_runs) {
        const float c = per_row(h, run.row);
        for (int t = 0; t < run.count; ++t) sh[t] += c;
        sh += run.count;
      }
    }
  }
  void add_weighted(const QueryKeys& set, const float* a, int heads, int r, int stride, float* rel) {
    per_row.setZero(heads, set.table->rows());
    for (int h = 0; h < heads; ++h) {
      const float* ah = a + h * stride + set.posed();
      for (const QueryKeys::TableRun& run : set.table_runs) {
        float sum = 0;
        for (int t = 0; t < run.count; ++t) sum += ah[t];
        per_row(h, run.row) += sum;
        ah += run.count;
      }
    }
    Eigen::Map<Mat>(rel, heads, r).noalias() += per_row.lazyProduct(*set.table);
  }
};

// Relation columns are read once per layer, and a busy server's decode call builds megabytes of them (more than the
// core's cache), so without help the relation-score kernel waits on memory for each query's (perf: two thirds of its
// samples on its loads). attend_one asks for the next query's columns in four parts between its own phases; asking
// for all of a set's lines at once stalled on the core's few pending-load slots.
void prefetch_relation_part(const QueryKeys* set, int part, int parts) {
  if (!set) return;
  const char* h = reinterpret_cast<const char*>(set->relation.data());
  const size_t lines = (static_cast<size_t>(set->relation.size()) * sizeof(float) + 63) / 64;
  for (size_t l = lines * part / parts; l < lines * (part + 1) / parts; ++l) __builtin_prefetch(h + l * 64);
}

// The same for the start of the next group's set (two lines of each of its rows), while a group of queries runs its
// products.
void prefetch_relation_start(const QueryKeys& set) {
  const int mp = set.posed();
  const float* h = set.relation.data();
  for (int c = 0; c < set.relation.rows() && mp > 0; ++c) {
    __builtin_prefetch(h + c * mp);
    if (mp > 16) __builtin_prefetch(h + c * mp + 16);
  }
}

// One query with its own key set, all heads at once: scores (heads x m) from the key rows in place (a gather would
// copy each row for one use), the relation terms, softmax, then the weighted values (written to `out`, heads x dh,
// which holds zeros) and the weighted relation embedding (written to `rel_out`, heads x r). `next`: the key set of
// the query that runs next on this thread, if another, whose relation columns are asked for on the way.
void attend_one(const AttentionShape& shape, const float* q, const float* u, const QueryKeys& set,
                const KeyValueRows& kv, float scale, std::vector<float>& scores, std::vector<float>& inv,
                TableTerms& table, float* out, float* rel_out, const QueryKeys* next) {
  const int m = static_cast<int>(set.keys.size());
  const int mp = set.posed();
  scores.resize(static_cast<size_t>(shape.heads) * m);  // a vector: it keeps its capacity as m changes
  prefetch_relation_part(next, 0, 4);
  if (kv.kh) kernel_key_scores_f16(shape, q, kv.kh, set.keys.data(), m, scores.data());
  else kernel_key_scores(shape, q, kv.k, set.keys.data(), m, scores.data());
  if (!set.uniform) {
    kernel_relation_scores(shape, u, set.relation.data(), mp, scores.data(), m);
    if (mp < m) table.add_scores(set, u, shape.heads, shape.r, scores.data(), m);
  }
  // The weights stay unnormalised; the weighted sums are scaled by each head's 1 / sum instead (one pass fewer).
  inv.resize(shape.heads);
  prefetch_relation_part(next, 1, 4);
  kernel_softmax_rows(scores.data(), shape.heads, m, m, scale, inv.data());
  prefetch_relation_part(next, 2, 4);
  if (kv.kh) kernel_weighted_values_f16(shape, scores.data(), kv.vh, set.keys.data(), m, out);
  else kernel_weighted_values(shape, scores.data(), kv.v, set.keys.data(), m, out);
  for (int h = 0; h < shape.heads; ++h)
    for (int c = 0; c < shape.dh; ++c) out[h * shape.dh + c] *= inv[h];
  prefetch_relation_part(next, 3, 4);
  if (set.uniform) {  // the weights sum to one
    Eigen::Map<Mat>(rel_out, shape.heads, shape.r).rowwise() = set.table->row(set.table_runs[0].row);
    return;
  }
  kernel_weighted_relation(shape, scores.data(), set.relation.data(), mp, m, rel_out);
  if (mp < m) table.add_weighted(set, scores.data(), shape.heads, shape.r, m, rel_out);
  for (int h = 0; h < shape.heads; ++h)
    for (int c = 0; c < shape.r; ++c) rel_out[h * shape.r + c] *= inv[h];
}

}  // namespace

Mat relative_attention(const Mat& x, const AttentionParams& p, int heads, const MatMap& k, const MatMap& v,
                       std::span<const QueryKeys* const> query_keys, ThreadPool* pool) {
  return relative_attention(x, p, heads, KeyValueRows(k, v), query_keys, pool);
}

namespace {

// A thread's scratch for the groups it runs.
struct GroupScratch {
  Mat kg, vg, s, og, ug, rg, qh;
  std::vector<float> scores;  // attend_one's heads x m
  std::vector<float> inv;  // 1 / the sum of each row's unnormalised weights (per head, or per query of a group)
  TableTerms table;
};

// What one call of relative_attention needs besides its result, kept by each calling thread from call to call: a
// step calls it 8 times per batch, and allocating these each time (a map of groups, the groups' scratch) was 2-3 %
// of a step. A pool serves one caller at a time, so the caller's workers[k] is worker k's alone during a call.
struct CallScratch {
  std::vector<std::pair<const QueryKeys*, int>> by_set;  // (key set, row), sorted: the groups are its runs
  std::vector<int> rows;                                 // by_set's rows in its order; a group is a span of them
  std::vector<std::pair<const QueryKeys*, std::span<const int>>> groups;
  std::vector<GroupScratch> workers;  // per thread of the pool (one without a pool)
};
thread_local CallScratch call_scratch;

}  // namespace

Mat relative_attention(const Mat& x, const AttentionParams& p, int heads, const KeyValueRows& kv,
                       std::span<const QueryKeys* const> query_keys, ThreadPool* pool) {
  const int n = static_cast<int>(x.rows());
  const int d = static_cast<int>(x.cols());
  const int dh = d / heads;
  const int r = p.rel_key.in;
  const float scale = 1.0f / std::sqrt(static_cast<float>(dh));
  const AttentionShape shape{heads, dh, r};
  const Mat q = linear(x, p.query);
  const Mat q_rel = linear(x, p.rel_query);
  const MatMap w_rk = p.rel_key.w();    // [d, r]
  const MatMap w_rv = p.rel_value.w();  // [d, r]
  // u_i^h = W_rk^h^T q'_i^h: the relation query of each head, n x (heads * r).
  Mat u(n, heads * r);
  for (int h = 0; h < heads; ++h)
    u.middleCols(h * r, r).noalias() = q_rel.middleCols(h * dh, dh) * w_rk.middleRows(h * dh, dh);

  // Queries reading the same key set go together: the rows sorted by key set (then by row), a group a run of them.
  // Each group writes its own rows of o and rel only, so groups may run on any thread in any order.
  CallScratch& cs = call_scratch;  // the calling thread's; the pool's workers reach it through this reference
  cs.by_set.resize(n);
  for (int i = 0; i < n; ++i) cs.by_set[i] = {query_keys[i], i};
  std::sort(cs.by_set.begin(), cs.by_set.end());
  cs.rows.resize(n);
  for (int i = 0; i < n; ++i) cs.rows[i] = cs.by_set[i].second;
  cs.groups.clear();
  for (int i = 0, end; i < n; i = end) {
    for (end = i + 1; end < n && cs.by_set[end].first == cs.by_set[i].first; ++end) {
    }
    if (!cs.by_set[i].first->keys.empty())  // no keys: the output is the relation-value bias alone
      cs.groups.push_back({cs.by_set[i].first, std::span<const int>(cs.rows.data() + i, end - i)});
  }

  Mat o = Mat::Zero(n, d);            // attention-weighted values
  Mat rel = Mat::Zero(n, heads * r);  // attention-weighted relation embeddings, projected by W_rv below
  const size_t workers = pool ? pool->threads() + 1 : 1;  // the caller (thread 0) and the pool's threads
  if (cs.workers.size() < workers) cs.workers.resize(workers);
  auto run_group = [&](int group, int thread) {
    const QueryKeys* set = cs.groups[group].first;
    const std::span<const int> rows = cs.groups[group].second;
    GroupScratch& t = cs.workers[thread];
    const int m = static_cast<int>(set->keys.size());
    const int g = static_cast<int>(rows.size());
    const int mp = set->posed();
    const QueryKeys* next = group + 1 < static_cast<int>(cs.groups.size()) ? cs.groups[group + 1].first : nullptr;
    if (g <= 2) {  // the last query asks for the next set's relation columns as it goes
      for (int c = 0; c < g; ++c)
        attend_one(shape, q.row(rows[c]).data(), u.row(rows[c]).data(), *set, kv, scale, t.scores, t.inv, t.table,
                   o.row(rows[c]).data(), rel.row(rows[c]).data(), c == g - 1 ? next : nullptr);
      return;
    }
    if (next) prefetch_relation_start(*next);
    // Keys 0..m-1 in order (a whole map): its bf16 tiles where it has them, else its floats read in place;
    // otherwise gather the rows once for the group (converting half floats).
    const bool whole = m == kv.rows && std::is_sorted(set->keys.begin(), set->keys.end()) &&
                       set->keys.front() == 0 && set->keys.back() == m - 1;
    const bool bf16 = whole && kv.k_bf16;
    const bool identity = whole && !kv.half();
    if (!identity && !bf16) {
      t.kg.resize(m, d);
      t.vg.resize(m, d);
      for (int j = 0; j < m; ++j) {
        const size_t at = static_cast<size_t>(set->keys[j]) * d;
        if (kv.kh) {
          halves_to_floats(kv.kh + at, d, t.kg.row(j).data());
          halves_to_floats(kv.vh + at, d, t.vg.row(j).data());
        } else {
          std::copy_n(kv.k + at, d, t.kg.row(j).data());
          std::copy_n(kv.v + at, d, t.vg.row(j).data());
        }
      }
    }
    // The keys and values as floats, read by the fp32 products only.
    const MatMap kk = identity ? MatMap(kv.k, m, d) : MatMap(t.kg.data(), m, d);
    const MatMap vv = identity ? MatMap(kv.v, m, d) : MatMap(t.vg.data(), m, d);
    for (int h = 0; h < heads; ++h) {
      // Scores, queries down and keys across: g x m.
      if (bf16) {
        t.qh = q(rows, Eigen::seqN(h * dh, dh));
        t.s.resize(g, m);
        bf16_linear(t.qh.data(), g, kv.k_bf16[h], t.s.data());
      } else {
        t.s.noalias() = q(rows, Eigen::seqN(h * dh, dh)) * kk.middleCols(h * dh, dh).transpose();
      }
      t.ug = u(rows, Eigen::seqN(h * r, r));  // g x r
      if (!set->uniform) {
        t.s.leftCols(mp).noalias() += t.ug * set->relation;
        if (mp < m) t.table.add_scores(*set, t.ug.data(), g, r, t.s.data(), m);
      }
      t.inv.resize(g);
      kernel_softmax_rows(t.s.data(), g, m, m, scale, t.inv.data());  // unnormalised, as in attend_one
      if (bf16) {
        t.og.resize(g, dh);
        bf16_linear(t.s.data(), g, kv.v_bf16[h], t.og.data());
      } else {
        t.og.noalias() = t.s * vv.middleCols(h * dh, dh);  // g x dh
      }
      for (int c = 0; c < g; ++c) o.row(rows[c]).segment(h * dh, dh) = t.og.row(c) * t.inv[c];
      if (set->uniform) {  // the weights sum to one: each query's weighted relation is the table's one row
        const auto only = set->table->row(set->table_runs[0].row);
        for (int c = 0; c < g; ++c) rel.row(rows[c]).segment(h * r, r) = only;
        continue;
      }
      t.rg.noalias() = t.s.leftCols(mp) * set->relation.transpose();  // g x r
      if (mp < m) t.table.add_weighted(*set, t.s.data(), g, r, m, t.rg.data());
      for (int c = 0; c < g; ++c) rel.row(rows[c]).segment(h * r, r) = t.rg.row(c) * t.inv[c];
    }
  };
  const int tasks = static_cast<int>(cs.groups.size());
  if (pool) pool->parallel_for(tasks, run_group);
  else
    for (int i = 0; i < tasks; ++i) run_group(i, 0);
  // out_i^h += W_rv^h (sum_j a_ij h_ij) + b_rv^h
  for (int h = 0; h < heads; ++h)
    o.middleCols(h * dh, dh).noalias() += rel.middleCols(h * r, r) * w_rv.middleRows(h * dh, dh).transpose();
  o.rowwise() += VecMap(p.rel_value.bias, d);
  return linear(o, p.output);
}

}  // namespace ss
