// The inner loops of attention for one query over its own key set, all heads at once. Each has a plain C++ form
// and, when the build targets AVX-512 (or AVX2 with FMA), a register-blocked form; both compute the same sums (tests compare them).
//
// Layouts: a key/value row is d = heads * dh floats (head h at h * dh); `keys` names rows of a row-major matrix;
// scores and weights are heads x m, row-major; relation embeddings are stored key-major, r x m (row c holds feature c
// of every key), so the relation kernels run a vector of keys at a time with no horizontal sums per key.
#pragma once

#include <cstdint>

namespace ss {

struct AttentionShape {
  int heads = 0, dh = 0, r = 0;  // heads, width per head, relation width
  int d() const { return heads * dh; }
};

// scores[h][j] = q_h . k_{keys[j], h}
void kernel_key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m, float* scores);
// scores[h][j] += sum_c u[h][c] rel_t[c][j] for j < m   (u: heads x r, the relation query of each head; rel_t: r x m;
// scores rows `stride` apart)
void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel_t, int m, float* scores,
                            int stride);
// out[h] += sum_j a[h][j] v_{keys[j], h}   (out: d floats)
void kernel_weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m, float* out);
// out[h][c] = sum_{j < m} a[h][j] rel_t[c][j]   (out: heads x r; rel_t: r x m; rows of a `stride` apart)
void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel_t, int m, int stride,
                              float* out);

// Each of `rows` rows of s (`cols` floats, rows `stride` apart) becomes softmax(scale * row), in place (scale > 0).
// With `inv_sums` (rows floats), the rows are left unnormalised (exp of scale * (row - max)) and inv_sums[i] is the
// reciprocal of row i's sum: a caller whose next step is linear in the weights scales its results instead.
void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale, float* inv_sums = nullptr);

// dst (cols x rows) = src (rows x cols) transposed, both row-major: a key set's relation columns from its embeddings
// (Eigen's element-by-element transpose of them was 2 % of a busy server's time).
void kernel_transpose(const float* src, int rows, int cols, float* dst);

// Keys and values stored as IEEE half floats (binary16, as uint16_t), converted to float for the math: the same
// sums as the forms above on the converted rows.
void kernel_key_scores_f16(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m,
                           float* scores);
void kernel_weighted_values_f16(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys, int m,
                                float* out);
// Rounds n floats to half floats (nearest, ties to even; beyond the half range: +-65504) and back.
void floats_to_halves(const float* x, int n, uint16_t* out);
void halves_to_floats(const uint16_t* x, int n, float* out);

// The plain forms (what the fast forms must equal up to float rounding); exposed for the tests.
void kernel_key_scores_plain(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                             float* scores);
void kernel_relation_scores_plain(const AttentionShape& s, const float* u, const float* rel_t, int m, float* scores,
                                  int stride);
void kernel_weighted_values_plain(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                                  float* out);
void kernel_weighted_relation_plain(const AttentionShape& s, const float* a, const float* rel_t, int m, int stride,
                                    float* out);
void kernel_softmax_rows_plain(float* s, int rows, int cols, int stride, float scale, float* inv_sums = nullptr);
void kernel_transpose_plain(const float* src, int rows, int cols, float* dst);
void kernel_key_scores_f16_plain(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m,
                                 float* scores);
void kernel_weighted_values_f16_plain(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys,
                                      int m, float* out);
float half_to_float(uint16_t h);
uint16_t float_to_half(float x);

}  // namespace ss
