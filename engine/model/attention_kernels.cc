#include "engine/model/attention_kernels.h"

#include <immintrin.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace ss {

void kernel_key_scores_plain(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                             float* scores) {
  for (int j = 0; j < m; ++j) {
    const float* kr = k + static_cast<size_t>(keys[j]) * s.d();
    for (int h = 0; h < s.heads; ++h) {
      float sum = 0;
      for (int c = h * s.dh; c < (h + 1) * s.dh; ++c) sum += q[c] * kr[c];
      scores[h * m + j] = sum;
    }
  }
}

void kernel_relation_scores_plain(const AttentionShape& s, const float* u, const float* rel, int m, float* scores,
                                  int stride) {
  for (int h = 0; h < s.heads; ++h)
    for (int c = 0; c < s.r; ++c)
      for (int j = 0; j < m; ++j) scores[h * stride + j] += u[h * s.r + c] * rel[j * s.r + c];
}

void kernel_weighted_values_plain(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                                  float* out) {
  for (int j = 0; j < m; ++j) {
    const float* vr = v + static_cast<size_t>(keys[j]) * s.d();
    for (int h = 0; h < s.heads; ++h)
      for (int c = h * s.dh; c < (h + 1) * s.dh; ++c) out[c] += a[h * m + j] * vr[c];
  }
}

void kernel_weighted_relation_plain(const AttentionShape& s, const float* a, const float* rel, int m, int stride,
                                    float* out) {
  for (int h = 0; h < s.heads; ++h)
    for (int c = 0; c < s.r; ++c) {
      float sum = 0;
      for (int j = 0; j < m; ++j) sum += a[h * stride + j] * rel[j * s.r + c];
      out[h * s.r + c] = sum;
    }
}

void kernel_softmax_rows_plain(float* s, int rows, int cols, int stride, float scale) {
  for (int i = 0; i < rows; ++i) {
    float* row = s + static_cast<size_t>(i) * stride;
    const float top = *std::max_element(row, row + cols);
    float sum = 0;
    for (int j = 0; j < cols; ++j) sum += (row[j] = std::exp((row[j] - top) * scale));
    for (int j = 0; j < cols; ++j) row[j] /= sum;
  }
}

#if defined(__AVX512F__)
namespace {

// The sums of four vectors, in lanes 0, 4, 8 and 12 of the result.
inline __m512 sum4(__m512 a, __m512 b, __m512 c, __m512 d) {
  const __m512 ab = _mm512_add_ps(_mm512_shuffle_f32x4(a, b, 0x44), _mm512_shuffle_f32x4(a, b, 0xEE));
  const __m512 cd = _mm512_add_ps(_mm512_shuffle_f32x4(c, d, 0x44), _mm512_shuffle_f32x4(c, d, 0xEE));
  __m512 z = _mm512_add_ps(_mm512_shuffle_f32x4(ab, cd, 0x88), _mm512_shuffle_f32x4(ab, cd, 0xDD));
  z = _mm512_add_ps(z, _mm512_permute_ps(z, 0x4E));
  return _mm512_add_ps(z, _mm512_permute_ps(z, 0xB1));
}

inline void store4(__m512 z, float* p0, float* p1, float* p2, float* p3) {
  alignas(64) float lanes[16];
  _mm512_store_ps(lanes, z);
  *p0 = lanes[0];
  *p1 = lanes[4];
  *p2 = lanes[8];
  *p3 = lanes[12];
}

// HV = dh / 16 vectors per head (1 or 2); heads in groups of four.
template <int HV>
void key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m, float* scores) {
  const int d = s.d();
  for (int j = 0; j < m; ++j) {
    const float* kr = k + static_cast<size_t>(keys[j]) * d;
    for (int h = 0; h < s.heads; h += 4) {
      __m512 acc[4];
      for (int g = 0; g < 4; ++g) {
        const int base = (h + g) * s.dh;
        acc[g] = _mm512_mul_ps(_mm512_loadu_ps(q + base), _mm512_loadu_ps(kr + base));
        if constexpr (HV == 2)
          acc[g] = _mm512_fmadd_ps(_mm512_loadu_ps(q + base + 16), _mm512_loadu_ps(kr + base + 16), acc[g]);
      }
      store4(sum4(acc[0], acc[1], acc[2], acc[3]), scores + h * m + j, scores + (h + 1) * m + j,
             scores + (h + 2) * m + j, scores + (h + 3) * m + j);
    }
  }
}

template <int HV>
void weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m, float* out) {
  const int d = s.d();
  for (int h = 0; h < s.heads; h += 4) {
    __m512 acc[4 * HV];
    for (int i = 0; i < 4 * HV; ++i) acc[i] = _mm512_loadu_ps(out + h * s.dh + 16 * i);
    for (int j = 0; j < m; ++j) {
      const float* vr = v + static_cast<size_t>(keys[j]) * d + h * s.dh;
      for (int g = 0; g < 4; ++g) {
        const __m512 w = _mm512_set1_ps(a[(h + g) * m + j]);
        for (int i = 0; i < HV; ++i)
          acc[g * HV + i] = _mm512_fmadd_ps(w, _mm512_loadu_ps(vr + g * s.dh + 16 * i), acc[g * HV + i]);
      }
    }
    for (int i = 0; i < 4 * HV; ++i) _mm512_storeu_ps(out + h * s.dh + 16 * i, acc[i]);
  }
}

bool fast_shape(const AttentionShape& s) { return s.heads % 4 == 0 && (s.dh == 16 || s.dh == 32); }

}  // namespace

void kernel_key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                       float* scores) {
  if (!fast_shape(s)) return kernel_key_scores_plain(s, q, k, keys, m, scores);
  if (s.dh == 32) return key_scores<2>(s, q, k, keys, m, scores);
  key_scores<1>(s, q, k, keys, m, scores);
}

void kernel_weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                            float* out) {
  if (!fast_shape(s)) return kernel_weighted_values_plain(s, a, v, keys, m, out);
  if (s.dh == 32) return weighted_values<2>(s, a, v, keys, m, out);
  weighted_values<1>(s, a, v, keys, m, out);
}

void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel, int m, float* scores,
                            int stride) {
  if (s.heads % 4 != 0 || s.r != 32) return kernel_relation_scores_plain(s, u, rel, m, scores, stride);
  for (int h = 0; h < s.heads; h += 4) {
    __m512 uh[8];
    for (int g = 0; g < 4; ++g)
      for (int i = 0; i < 2; ++i) uh[g * 2 + i] = _mm512_loadu_ps(u + (h + g) * s.r + 16 * i);
    for (int j = 0; j < m; ++j) {
      const __m512 r0 = _mm512_loadu_ps(rel + j * s.r), r1 = _mm512_loadu_ps(rel + j * s.r + 16);
      __m512 acc[4];
      for (int g = 0; g < 4; ++g) acc[g] = _mm512_fmadd_ps(uh[g * 2 + 1], r1, _mm512_mul_ps(uh[g * 2], r0));
      alignas(64) float lanes[16];
      _mm512_store_ps(lanes, sum4(acc[0], acc[1], acc[2], acc[3]));
      for (int g = 0; g < 4; ++g) scores[(h + g) * stride + j] += lanes[4 * g];
    }
  }
}

void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel, int m, int stride,
                              float* out) {
  if (s.heads % 4 != 0 || s.r != 32) return kernel_weighted_relation_plain(s, a, rel, m, stride, out);
  for (int h = 0; h < s.heads; h += 4) {
    __m512 acc[8];
    for (int i = 0; i < 8; ++i) acc[i] = _mm512_setzero_ps();
    for (int j = 0; j < m; ++j) {
      const __m512 r0 = _mm512_loadu_ps(rel + j * s.r), r1 = _mm512_loadu_ps(rel + j * s.r + 16);
      for (int g = 0; g < 4; ++g) {
        const __m512 w = _mm512_set1_ps(a[(h + g) * stride + j]);
        acc[g * 2] = _mm512_fmadd_ps(w, r0, acc[g * 2]);
        acc[g * 2 + 1] = _mm512_fmadd_ps(w, r1, acc[g * 2 + 1]);
      }
    }
    for (int g = 0; g < 4; ++g)
      for (int i = 0; i < 2; ++i) _mm512_storeu_ps(out + (h + g) * s.r + 16 * i, acc[g * 2 + i]);
  }
}

void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale) {
  // Whole vectors, the last one masked (its empty lanes read as -inf, whose exp is 0): no scalar exp for a tail.
  const __m512 lowest = _mm512_set1_ps(-std::numeric_limits<float>::infinity());
  const int full = cols / 16;
  const __mmask16 tail = static_cast<__mmask16>((1u << (cols % 16)) - 1);
  for (int i = 0; i < rows; ++i) {
    float* row = s + static_cast<size_t>(i) * stride;
    __m512 top = lowest;
    for (int b = 0; b < full; ++b) top = _mm512_max_ps(top, _mm512_loadu_ps(row + 16 * b));
    if (tail) top = _mm512_max_ps(top, _mm512_mask_loadu_ps(lowest, tail, row + 16 * full));
    const __m512 shift = _mm512_set1_ps(_mm512_reduce_max_ps(top));
    const __m512 k = _mm512_set1_ps(scale);
    __m512 sum = _mm512_setzero_ps();
    auto exp_at = [&](__m512 x) { return Eigen::internal::pexp(_mm512_mul_ps(_mm512_sub_ps(x, shift), k)); };
    for (int b = 0; b < full; ++b) {
      const __m512 e = exp_at(_mm512_loadu_ps(row + 16 * b));
      _mm512_storeu_ps(row + 16 * b, e);
      sum = _mm512_add_ps(sum, e);
    }
    if (tail) {
      const __m512 e = exp_at(_mm512_mask_loadu_ps(lowest, tail, row + 16 * full));
      _mm512_mask_storeu_ps(row + 16 * full, tail, e);
      sum = _mm512_add_ps(sum, e);
    }
    const __m512 inv = _mm512_set1_ps(1.0f / _mm512_reduce_add_ps(sum));
    for (int b = 0; b < full; ++b) _mm512_storeu_ps(row + 16 * b, _mm512_mul_ps(_mm512_loadu_ps(row + 16 * b), inv));
    if (tail)
      _mm512_mask_storeu_ps(row + 16 * full, tail, _mm512_mul_ps(_mm512_maskz_loadu_ps(tail, row + 16 * full), inv));
  }
}

#else  // no AVX-512: the plain forms

void kernel_key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                       float* scores) {
  kernel_key_scores_plain(s, q, k, keys, m, scores);
}
void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel, int m, float* scores,
                            int stride) {
  kernel_relation_scores_plain(s, u, rel, m, scores, stride);
}
void kernel_weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                            float* out) {
  kernel_weighted_values_plain(s, a, v, keys, m, out);
}
void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel, int m, int stride,
                              float* out) {
  kernel_weighted_relation_plain(s, a, rel, m, stride, out);
}
void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale) {
  kernel_softmax_rows_plain(s, rows, cols, stride, scale);
}

#endif

}  // namespace ss
