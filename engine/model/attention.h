// Sparse relative attention (paper appendix C.3, folded as docs/design.md section 7, relative attention):
//   score_ij = (q_i . k_j + q'_i . r_ij) / sqrt(head_dim),  r_ij = W_rk h_ij + b_rk,
//   out_i    = sum_j a_ij (v_j + W_rv h_ij + b_rv),
// with h_ij = relu(fc2(relu(fc1(f_ij)))) a relation embedding shared by all layers of one attention kind.
// q'_i . r_ij is computed as (W_rk^T q'_i) . h_ij: one dot product of relation_dim per pair and head instead of a
// projection per pair. (q'_i . b_rk is the same for every key of a query, so it cancels in the softmax.)
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/model/linalg.h"
#include "engine/model/vocab.h"
#include "engine/base/thread_pool.h"

namespace ss {

struct AttentionParams {
  LinearParams query, key, value, output, rel_query, rel_key, rel_value;
};

struct RelationParams {
  LinearParams fc1, fc2;
};

// A query's or key's place in space and time (with the heading's cosine and sine, computed once per token).
struct Anchor {
  bool has_pose = false;
  Pose pose;
  int step = 0;
  double cos_h = 1, sin_h = 0;

  Anchor() = default;
  Anchor(bool has, const Pose& p, int t)
      : has_pose(has), pose(p), step(t), cos_h(std::cos(p.heading)), sin_h(std::sin(p.heading)) {}
};

using RelationFeatures = std::array<float, kRelationFeatures>;
// f_ij of key `k` seen from query `q`: the key's offset in the query's frame (dx, dy) and distance, in units of
// 10 m; sin and cos of the heading difference; the step difference / 5; and 1 when both have a position. Without
// a position on either side the spatial features are 0.
RelationFeatures relation_features(const Anchor& q, const Anchor& k);

// h = relu(fc2(relu(fc1(f)))) for a batch of feature rows (m x 7 -> m x relation_dim).
Mat relation_embedding(const Mat& features, const RelationParams& p);
// The same, key-major as QueryKeys::relation holds it (relation_dim x m): the rows above, transposed.
Mat relation_columns(const Mat& features, const RelationParams& p);
// h for a pair of which at least one side has no position: it depends only on the step difference dt. Row dt
// (0 <= dt < steps) of the result (steps x relation_dim) is h of f = (0, 0, 0, 0, 0, dt / 5, 0).
Mat relation_by_step(const RelationParams& p, int steps);

// The keys one query reads: rows of the key/value matrices and their relation embeddings. Keys whose pair has
// positions on both sides come first, each with its own column of `relation`; the others (a side without a position)
// share the rows of a small table (their h depends only on the step difference), so they cost no memory of their
// own. Each part is in sequence order (for a KV cache, the rows are ring rows, so not always ascending).
struct QueryKeys {
  struct TableRun {
    int row = 0, count = 0;  // `count` consecutive keys that share row `row` of the table
  };
  std::vector<int> keys;
  Mat relation;                      // relation_dim x posed(), key-major: column j is h of keys[j] (the kernels run
                                     // a vector of keys at a time)
  const Mat* table = nullptr;        // rows of h shared by the remaining keys (relation_by_step), when there are any
  std::vector<TableRun> table_runs;  // keys[posed()..] in runs by table row (keys in sequence order share their
                                     // step difference, so the runs are few and long)
  bool uniform = false;              // no posed keys and one table row for all: the relation term is then one
                                     // constant per query and head, which the softmax cancels, and is skipped

  int posed() const { return static_cast<int>(relation.cols()); }
  // Appends the table row of the next key after the posed ones.
  void add_table_row(int row) {
    if (!table_runs.empty() && table_runs.back().row == row) ++table_runs.back().count;
    else table_runs.push_back({row, 1});
  }
};

// Each set's relation columns from its feature rows (features[i]: set i's posed keys x kRelationFeatures, row-major),
// the same bits as relation_columns on each alone (with the MLP's second layer in bf16: as with the AVX512-BF16
// product, in one fused pass, engine/model/relation_bf16.h).
void set_relation_columns(std::span<QueryKeys* const> sets, std::span<const std::vector<float>> features,
                          const RelationParams& p);

// The keys and values attention may read: rows of two row-major matrices (d floats per row), stored as floats or as
// half floats (binary16; the math converts them to float).
struct KeyValueRows {
  const float *k = nullptr, *v = nullptr;        // float storage
  const uint16_t *kh = nullptr, *vh = nullptr;   // half storage (when k is null), or beside it the same rows in half
                                                 // floats: then queries with keys of their own read these, and
                                                 // only groups that read every row in order read k
  int rows = 0, d = 0;
  // Optional: per head, the keys (rows x dh) and the values transposed (dh x rows) in bf16 tiles. Queries that read
  // every row together then run their two products in bf16.
  const Bf16Weight *k_bf16 = nullptr, *v_bf16 = nullptr;

  KeyValueRows() = default;
  KeyValueRows(const MatMap& keys, const MatMap& values)
      : k(keys.data()), v(values.data()), rows(static_cast<int>(keys.rows())), d(static_cast<int>(keys.cols())) {}
  KeyValueRows(const uint16_t* keys, const uint16_t* values, int n, int width)
      : kh(keys), vh(values), rows(n), d(width) {}
  bool half() const { return k == nullptr; }
};

// Attention for a batch of queries. `x`: the queries' normalised inputs (n x d). `k`, `v`: projected keys and values
// of every key the queries may name. Queries that share one QueryKeys are computed together with matrix products.
// Returns the output projection (n x d). With a pool, the key sets' groups of queries run on its threads (the same
// bits as without).
Mat relative_attention(const Mat& x, const AttentionParams& p, int heads, const MatMap& k, const MatMap& v,
                       std::span<const QueryKeys* const> query_keys, ThreadPool* pool = nullptr);
Mat relative_attention(const Mat& x, const AttentionParams& p, int heads, const KeyValueRows& kv,
                       std::span<const QueryKeys* const> query_keys, ThreadPool* pool = nullptr);

}  // namespace ss
