// The inner loops of attention for one query over its own key set, all heads at once. Each has a plain C++ form
// and, when the build targets AVX-512, a register-blocked form; both compute the same sums (tests compare them).
//
// Layouts: a key/value row is d = heads * dh floats (head h at h * dh); `keys` names rows of a row-major matrix;
// scores and weights are heads x m, row-major; relation embeddings are m x r (row j for key j, read in order, which
// the hardware prefetcher follows).
#pragma once

namespace ss {

struct AttentionShape {
  int heads = 0, dh = 0, r = 0;  // heads, width per head, relation width
  int d() const { return heads * dh; }
};

// scores[h][j] = q_h . k_{keys[j], h}
void kernel_key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m, float* scores);
// scores[h][j] += u_h . rel[j] for j < m   (u: heads x r, the relation query of each head; scores rows `stride` apart)
void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel, int m, float* scores,
                            int stride);
// out[h] += sum_j a[h][j] v_{keys[j], h}   (out: d floats)
void kernel_weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m, float* out);
// out[h] = sum_{j < m} a[h][j] rel[j]   (out: heads x r; rows of a `stride` apart)
void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel, int m, int stride,
                              float* out);

// Each of `rows` rows of s (`cols` floats, rows `stride` apart) becomes softmax(scale * row), in place (scale > 0).
void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale);

// The plain forms (what the fast forms must equal up to float rounding); exposed for the tests.
void kernel_key_scores_plain(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                             float* scores);
void kernel_relation_scores_plain(const AttentionShape& s, const float* u, const float* rel, int m, float* scores,
                                  int stride);
void kernel_weighted_values_plain(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                                  float* out);
void kernel_weighted_relation_plain(const AttentionShape& s, const float* a, const float* rel, int m, int stride,
                                    float* out);
void kernel_softmax_rows_plain(float* s, int rows, int cols, int stride, float scale);

}  // namespace ss
