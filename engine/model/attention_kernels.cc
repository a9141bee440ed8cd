#include "engine/model/attention_kernels.h"

#include <immintrin.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <cstring>
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

void kernel_relation_scores_plain(const AttentionShape& s, const float* u, const float* rel_t, int m, float* scores,
                                  int stride) {
  for (int h = 0; h < s.heads; ++h)
    for (int c = 0; c < s.r; ++c)
      for (int j = 0; j < m; ++j) scores[h * stride + j] += u[h * s.r + c] * rel_t[c * m + j];
}

void kernel_weighted_values_plain(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                                  float* out) {
  for (int j = 0; j < m; ++j) {
    const float* vr = v + static_cast<size_t>(keys[j]) * s.d();
    for (int h = 0; h < s.heads; ++h)
      for (int c = h * s.dh; c < (h + 1) * s.dh; ++c) out[c] += a[h * m + j] * vr[c];
  }
}

void kernel_weighted_relation_plain(const AttentionShape& s, const float* a, const float* rel_t, int m, int stride,
                                    float* out) {
  for (int h = 0; h < s.heads; ++h)
    for (int c = 0; c < s.r; ++c) {
      float sum = 0;
      for (int j = 0; j < m; ++j) sum += a[h * stride + j] * rel_t[c * m + j];
      out[h * s.r + c] = sum;
    }
}

void kernel_softmax_rows_plain(float* s, int rows, int cols, int stride, float scale, float* inv_sums) {
  for (int i = 0; i < rows; ++i) {
    float* row = s + static_cast<size_t>(i) * stride;
    const float top = *std::max_element(row, row + cols);
    float sum = 0;
    for (int j = 0; j < cols; ++j) sum += (row[j] = std::exp((row[j] - top) * scale));
    if (inv_sums) {
      inv_sums[i] = 1.0f / sum;
      continue;
    }
    for (int j = 0; j < cols; ++j) row[j] /= sum;
  }
}

void kernel_transpose_plain(const float* src, int rows, int cols, float* dst) {
  for (int i = 0; i < rows; ++i)
    for (int c = 0; c < cols; ++c) dst[static_cast<size_t>(c) * rows + i] = src[static_cast<size_t>(i) * cols + c];
}

// binary16 <-> binary32 in software (the plain forms and builds without F16C).
float half_to_float(uint16_t h) {
  const uint32_t sign = static_cast<uint32_t>(h & 0x8000) << 16;
  uint32_t exp = (h >> 10) & 0x1f, man = h & 0x3ff, bits;
  if (exp == 0) {
    if (man == 0) {
      bits = sign;
    } else {  // subnormal: normalise
      int e = -1;
      do {
        ++e;
        man <<= 1;
      } while (!(man & 0x400));
      bits = sign | static_cast<uint32_t>(127 - 15 - e) << 23 | (man & 0x3ff) << 13;
    }
  } else if (exp == 31) {
    bits = sign | 0x7f800000u | man << 13;
  } else {
    bits = sign | (exp + 127 - 15) << 23 | man << 13;
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

uint16_t float_to_half(float x) {
  x = std::clamp(x, -65504.0f, 65504.0f);  // saturate: an overflow must not become an infinity in a softmax
  uint32_t bits;
  std::memcpy(&bits, &x, 4);
  const uint16_t sign = static_cast<uint16_t>((bits >> 16) & 0x8000);
  const uint32_t abs = bits & 0x7fffffffu;
  if (abs > 0x7f800000u) return sign | 0x7e00;  // NaN
  if (abs < 0x38800000u) {                      // below the smallest normal half: subnormal or zero
    // Half subnormals are multiples of 2^-24: round abs / 2^-24 to nearest even with a float addition.
    float v;
    std::memcpy(&v, &abs, 4);
    const float scaled = v * 16777216.0f;  // exact (a power of two)
    const float r = std::nearbyint(scaled);
    return sign | static_cast<uint16_t>(r);
  }
  // Normal: drop 13 mantissa bits, nearest even (a carry into the exponent is the right result).
  const uint32_t rounded = abs + 0xfffu + ((abs >> 13) & 1);
  return sign | static_cast<uint16_t>((rounded - (static_cast<uint32_t>(127 - 15) << 23)) >> 13);
}

void kernel_key_scores_f16_plain(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m,
                                 float* scores) {
  for (int j = 0; j < m; ++j) {
    const uint16_t* kr = k + static_cast<size_t>(keys[j]) * s.d();
    for (int h = 0; h < s.heads; ++h) {
      float sum = 0;
      for (int c = h * s.dh; c < (h + 1) * s.dh; ++c) sum += q[c] * half_to_float(kr[c]);
      scores[h * m + j] = sum;
    }
  }
}

void kernel_weighted_values_f16_plain(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys,
                                      int m, float* out) {
  for (int j = 0; j < m; ++j) {
    const uint16_t* vr = v + static_cast<size_t>(keys[j]) * s.d();
    for (int h = 0; h < s.heads; ++h)
      for (int c = h * s.dh; c < (h + 1) * s.dh; ++c) out[c] += a[h * m + j] * half_to_float(vr[c]);
  }
}

#if defined(__F16C__) && defined(__AVX2__)
void floats_to_halves(const float* x, int n, uint16_t* out) {
  const __m256 hi = _mm256_set1_ps(65504.0f), lo = _mm256_set1_ps(-65504.0f);
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 c = _mm256_min_ps(_mm256_max_ps(_mm256_loadu_ps(x + i), lo), hi);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), _mm256_cvtps_ph(c, _MM_FROUND_TO_NEAREST_INT));
  }
  for (; i < n; ++i) out[i] = float_to_half(x[i]);
}
void halves_to_floats(const uint16_t* x, int n, float* out) {
  int i = 0;
  for (; i + 8 <= n; i += 8)
    _mm256_storeu_ps(out + i, _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(x + i))));
  for (; i < n; ++i) out[i] = half_to_float(x[i]);
}
#else
void floats_to_halves(const float* x, int n, uint16_t* out) {
  for (int i = 0; i < n; ++i) out[i] = float_to_half(x[i]);
}
void halves_to_floats(const uint16_t* x, int n, float* out) {
  for (int i = 0; i < n; ++i) out[i] = half_to_float(x[i]);
}
#endif

#if defined(__AVX512F__)
// The half-float forms are the AVX-512 float kernels below on converted rows.
#elif defined(__F16C__) && defined(__AVX2__) && defined(__FMA__)
namespace {

inline __m256 load_h(const uint16_t* p) { return _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p))); }

inline __m128 sum4_h(__m256 a, __m256 b, __m256 c, __m256 d) {
  const __m256 ab = _mm256_hadd_ps(a, b), cd = _mm256_hadd_ps(c, d);
  const __m256 z = _mm256_hadd_ps(ab, cd);
  return _mm_add_ps(_mm256_castps256_ps128(z), _mm256_extractf128_ps(z, 1));
}

template <int DH>
void key_scores_h(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m, float* scores) {
  constexpr int HV = DH / 8;
  const int d = s.d();
  for (int j = 0; j < m; ++j) {
    const uint16_t* kr = k + static_cast<size_t>(keys[j]) * d;
    for (int h = 0; h < s.heads; h += 4) {
      __m256 acc[4];
      for (int g = 0; g < 4; ++g) {
        const int base = (h + g) * DH;
        acc[g] = _mm256_mul_ps(_mm256_loadu_ps(q + base), load_h(kr + base));
        for (int i = 1; i < HV; ++i)
          acc[g] = _mm256_fmadd_ps(_mm256_loadu_ps(q + base + 8 * i), load_h(kr + base + 8 * i), acc[g]);
      }
      alignas(16) float lanes[4];
      _mm_store_ps(lanes, sum4_h(acc[0], acc[1], acc[2], acc[3]));
      for (int g = 0; g < 4; ++g) scores[(h + g) * m + j] = lanes[g];
    }
  }
}

template <int DH>
void weighted_values_h(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys, int m,
                       float* out) {
  const int d = s.d();
  for (int c0 = 0; c0 < d; c0 += 64) {
    const int h0 = c0 / DH;
    __m256 acc[8];
    for (int i = 0; i < 8; ++i) acc[i] = _mm256_loadu_ps(out + c0 + 8 * i);
    for (int j = 0; j < m; ++j) {
      const uint16_t* vr = v + static_cast<size_t>(keys[j]) * d + c0;
      for (int i = 0; i < 8; ++i) {
        const __m256 w = _mm256_broadcast_ss(a + (h0 + 8 * i / DH) * m + j);
        acc[i] = _mm256_fmadd_ps(w, load_h(vr + 8 * i), acc[i]);
      }
    }
    for (int i = 0; i < 8; ++i) _mm256_storeu_ps(out + c0 + 8 * i, acc[i]);
  }
}

bool fast_shape_h(const AttentionShape& s) { return s.heads % 4 == 0 && (s.dh == 16 || s.dh == 32) && s.d() % 64 == 0; }

}  // namespace

void kernel_key_scores_f16(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m,
                           float* scores) {
  if (!fast_shape_h(s)) return kernel_key_scores_f16_plain(s, q, k, keys, m, scores);
  if (s.dh == 32) return key_scores_h<32>(s, q, k, keys, m, scores);
  key_scores_h<16>(s, q, k, keys, m, scores);
}

void kernel_weighted_values_f16(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys, int m,
                                float* out) {
  if (!fast_shape_h(s)) return kernel_weighted_values_f16_plain(s, a, v, keys, m, out);
  if (s.dh == 32) return weighted_values_h<32>(s, a, v, keys, m, out);
  weighted_values_h<16>(s, a, v, keys, m, out);
}
#else
void kernel_key_scores_f16(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m,
                           float* scores) {
  kernel_key_scores_f16_plain(s, q, k, keys, m, scores);
}
void kernel_weighted_values_f16(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys, int m,
                                float* out) {
  kernel_weighted_values_f16_plain(s, a, v, keys, m, out);
}
#endif

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

// The low min(n, 16) lanes: a last, partial block of keys.
inline __mmask16 first_lanes(int n) { return n >= 16 ? __mmask16(0xffff) : static_cast<__mmask16>((1u << n) - 1); }

// Asks for the cache lines of the `elems` elements from `p`, a part of a key or value row read a few keys later: a
// query's keys are rows scattered over the cache, which the hardware prefetchers cannot guess, and the kernels
// otherwise wait on each row's loads.
template <typename T>
inline void prefetch_row(const T* p, int elems) {
  const char* c = reinterpret_cast<const char*>(p);
  for (int b = 0; b < elems * static_cast<int>(sizeof(T)); b += 64) _mm_prefetch(c + b, _MM_HINT_T0);
}
constexpr int kPrefetchKeys = 8;  // how far ahead of the key being read

// Sixteen key or value elements as floats: loaded, or converted from half floats.
inline __m512 load16(const float* p) { return _mm512_loadu_ps(p); }
inline __m512 load16(const uint16_t* p) {
  return _mm512_cvtph_ps(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)));
}

// Lane i of the result is the sum of the sixteen lanes of v[i]: three rounds of pairwise shuffles and adds.
inline __m512 sum16(const __m512* v) {
  __m512 u[4];
  for (int i = 0; i < 4; ++i) {
    const __m512* w = v + 4 * i;
    // Within each 128-bit quarter: [w0 w1 w0 w1] partial sums, then [w0 w1 w2 w3].
    const __m512 a = _mm512_add_ps(_mm512_unpacklo_ps(w[0], w[1]), _mm512_unpackhi_ps(w[0], w[1]));
    const __m512 b = _mm512_add_ps(_mm512_unpacklo_ps(w[2], w[3]), _mm512_unpackhi_ps(w[2], w[3]));
    u[i] = _mm512_add_ps(_mm512_shuffle_ps(a, b, 0x44), _mm512_shuffle_ps(a, b, 0xEE));
  }
  // Across the quarters: quarter i of the result adds the four quarters of u[i].
  const __m512 u01 = _mm512_add_ps(_mm512_shuffle_f32x4(u[0], u[1], 0x44), _mm512_shuffle_f32x4(u[0], u[1], 0xEE));
  const __m512 u23 = _mm512_add_ps(_mm512_shuffle_f32x4(u[2], u[3], 0x44), _mm512_shuffle_f32x4(u[2], u[3], 0xEE));
  return _mm512_add_ps(_mm512_shuffle_f32x4(u01, u23, 0x88), _mm512_shuffle_f32x4(u01, u23, 0xDD));
}

// HV = dh / 16 vectors per head (1 or 2); heads in groups of four. T: float, or uint16_t for half floats. Four keys
// at a time: their sixteen (key, head) sums reduce in one vector, whose quarter g holds head g's four scores.
template <int HV, typename T>
void key_scores(const AttentionShape& s, const float* q, const T* k, const int* keys, int m, float* scores) {
  const int d = s.d();
  for (int h = 0; h < s.heads; h += 4) {
    __m512 qv[4 * HV];
    for (int g = 0; g < 4; ++g)
      for (int i = 0; i < HV; ++i) qv[g * HV + i] = _mm512_loadu_ps(q + (h + g) * s.dh + 16 * i);
    float* out = scores + static_cast<size_t>(h) * m;
    int j = 0;
    for (; j + 4 <= m; j += 4) {
      for (int e = 0; e < 4 && j + kPrefetchKeys + e < m; ++e)
        prefetch_row(k + static_cast<size_t>(keys[j + kPrefetchKeys + e]) * d + h * s.dh, 4 * s.dh);
      __m512 acc[16];  // acc[4 * g + key]
      for (int e = 0; e < 4; ++e) {
        const T* kr = k + static_cast<size_t>(keys[j + e]) * d + h * s.dh;
        for (int g = 0; g < 4; ++g) {
          acc[4 * g + e] = _mm512_mul_ps(qv[g * HV], load16(kr + g * s.dh));
          if constexpr (HV == 2)
            acc[4 * g + e] = _mm512_fmadd_ps(qv[g * HV + 1], load16(kr + g * s.dh + 16), acc[4 * g + e]);
        }
      }
      const __m512 z = sum16(acc);
      _mm_storeu_ps(out + j, _mm512_extractf32x4_ps(z, 0));
      _mm_storeu_ps(out + m + j, _mm512_extractf32x4_ps(z, 1));
      _mm_storeu_ps(out + 2 * m + j, _mm512_extractf32x4_ps(z, 2));
      _mm_storeu_ps(out + 3 * m + j, _mm512_extractf32x4_ps(z, 3));
    }
    for (; j < m; ++j) {
      const T* kr = k + static_cast<size_t>(keys[j]) * d + h * s.dh;
      __m512 acc[4];
      for (int g = 0; g < 4; ++g) {
        acc[g] = _mm512_mul_ps(qv[g * HV], load16(kr + g * s.dh));
        if constexpr (HV == 2) acc[g] = _mm512_fmadd_ps(qv[g * HV + 1], load16(kr + g * s.dh + 16), acc[g]);
      }
      store4(sum4(acc[0], acc[1], acc[2], acc[3]), out + j, out + m + j, out + 2 * m + j, out + 3 * m + j);
    }
  }
}

template <int HV, typename T>
void weighted_values(const AttentionShape& s, const float* a, const T* v, const int* keys, int m, float* out) {
  const int d = s.d();
  for (int h = 0; h < s.heads; h += 4) {
    __m512 acc[4 * HV];
    for (int i = 0; i < 4 * HV; ++i) acc[i] = _mm512_loadu_ps(out + h * s.dh + 16 * i);
    for (int j = 0; j < m; ++j) {
      if (j + kPrefetchKeys < m) prefetch_row(v + static_cast<size_t>(keys[j + kPrefetchKeys]) * d + h * s.dh, 4 * s.dh);
      const T* vr = v + static_cast<size_t>(keys[j]) * d + h * s.dh;
      for (int g = 0; g < 4; ++g) {
        const __m512 w = _mm512_set1_ps(a[(h + g) * m + j]);
        for (int i = 0; i < HV; ++i)
          acc[g * HV + i] = _mm512_fmadd_ps(w, load16(vr + g * s.dh + 16 * i), acc[g * HV + i]);
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

void kernel_key_scores_f16(const AttentionShape& s, const float* q, const uint16_t* k, const int* keys, int m,
                           float* scores) {
  if (!fast_shape(s)) return kernel_key_scores_f16_plain(s, q, k, keys, m, scores);
  if (s.dh == 32) return key_scores<2>(s, q, k, keys, m, scores);
  key_scores<1>(s, q, k, keys, m, scores);
}

void kernel_weighted_values_f16(const AttentionShape& s, const float* a, const uint16_t* v, const int* keys, int m,
                                float* out) {
  if (!fast_shape(s)) return kernel_weighted_values_f16_plain(s, a, v, keys, m, out);
  if (s.dh == 32) return weighted_values<2>(s, a, v, keys, m, out);
  weighted_values<1>(s, a, v, keys, m, out);
}

// Keys run sixteen to a vector: relation scores add u[h][c] rel_t[c][j..j+16) over c (the plain form's order), two
// blocks of keys at once for eight independent sums; the last block is masked.
void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel_t, int m, float* scores,
                            int stride) {
  if (s.heads % 4 != 0) return kernel_relation_scores_plain(s, u, rel_t, m, scores, stride);
  const int r = s.r;
  for (int h = 0; h < s.heads; h += 4) {
    float* sh = scores + static_cast<size_t>(h) * stride;
    const float* uh = u + h * r;
    int j = 0;
    for (; j + 32 <= m; j += 32) {
      __m512 acc[8];
      for (int g = 0; g < 4; ++g) {
        acc[2 * g] = _mm512_loadu_ps(sh + g * stride + j);
        acc[2 * g + 1] = _mm512_loadu_ps(sh + g * stride + j + 16);
      }
      for (int c = 0; c < r; ++c) {
        const __m512 x0 = _mm512_loadu_ps(rel_t + c * m + j), x1 = _mm512_loadu_ps(rel_t + c * m + j + 16);
        for (int g = 0; g < 4; ++g) {
          const __m512 w = _mm512_set1_ps(uh[g * r + c]);
          acc[2 * g] = _mm512_fmadd_ps(w, x0, acc[2 * g]);
          acc[2 * g + 1] = _mm512_fmadd_ps(w, x1, acc[2 * g + 1]);
        }
      }
      for (int g = 0; g < 4; ++g) {
        _mm512_storeu_ps(sh + g * stride + j, acc[2 * g]);
        _mm512_storeu_ps(sh + g * stride + j + 16, acc[2 * g + 1]);
      }
    }
    for (; j < m; j += 16) {
      const __mmask16 lanes = first_lanes(m - j);
      __m512 acc[4];
      for (int g = 0; g < 4; ++g) acc[g] = _mm512_maskz_loadu_ps(lanes, sh + g * stride + j);
      for (int c = 0; c < r; ++c) {
        const __m512 x = _mm512_maskz_loadu_ps(lanes, rel_t + c * m + j);
        for (int g = 0; g < 4; ++g) acc[g] = _mm512_fmadd_ps(_mm512_set1_ps(uh[g * r + c]), x, acc[g]);
      }
      for (int g = 0; g < 4; ++g) _mm512_mask_storeu_ps(sh + g * stride + j, lanes, acc[g]);
    }
  }
}

// Four heads by four relation features at a time: sixteen sums over the keys, sixteen to a vector (the last block
// masked), reduced once at the end.
void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel_t, int m, int stride,
                              float* out) {
  if (s.heads % 4 != 0 || s.r % 4 != 0)
    return kernel_weighted_relation_plain(s, a, rel_t, m, stride, out);
  const int r = s.r;
  for (int h = 0; h < s.heads; h += 4) {
    const float* ah = a + static_cast<size_t>(h) * stride;
    for (int c = 0; c < r; c += 4) {
      __m512 acc[16];
      for (int i = 0; i < 16; ++i) acc[i] = _mm512_setzero_ps();
      for (int j = 0; j < m; j += 16) {
        const __mmask16 lanes = first_lanes(m - j);
        __m512 w[4], x[4];
        for (int g = 0; g < 4; ++g) w[g] = _mm512_maskz_loadu_ps(lanes, ah + g * stride + j);
        for (int e = 0; e < 4; ++e) x[e] = _mm512_maskz_loadu_ps(lanes, rel_t + (c + e) * m + j);
        for (int g = 0; g < 4; ++g)
          for (int e = 0; e < 4; ++e) acc[4 * g + e] = _mm512_fmadd_ps(w[g], x[e], acc[4 * g + e]);
      }
      for (int g = 0; g < 4; ++g) {
        float* o = out + (h + g) * r + c;
        store4(sum4(acc[4 * g], acc[4 * g + 1], acc[4 * g + 2], acc[4 * g + 3]), o, o + 1, o + 2, o + 3);
      }
    }
  }
}

void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale, float* inv_sums) {
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
    const float inv_sum = 1.0f / _mm512_reduce_add_ps(sum);
    if (inv_sums) {
      inv_sums[i] = inv_sum;
      continue;
    }
    const __m512 inv = _mm512_set1_ps(inv_sum);
    for (int b = 0; b < full; ++b) _mm512_storeu_ps(row + 16 * b, _mm512_mul_ps(_mm512_loadu_ps(row + 16 * b), inv));
    if (tail)
      _mm512_mask_storeu_ps(row + 16 * full, tail, _mm512_mul_ps(_mm512_maskz_loadu_ps(tail, row + 16 * full), inv));
  }
}

// In 16 x 16 blocks, the edges masked.
void kernel_transpose(const float* src, int rows, int cols, float* dst) {
  using Eigen::internal::Packet16f;
  for (int i0 = 0; i0 < rows; i0 += 16) {
    const int ni = std::min(16, rows - i0);
    for (int c0 = 0; c0 < cols; c0 += 16) {
      const int nc = std::min(16, cols - c0);
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wignored-attributes"  // Packet16f as a template argument, as in Eigen's own code
      Eigen::internal::PacketBlock<Packet16f, 16> b;
#pragma GCC diagnostic pop
      for (int i = 0; i < 16; ++i)
        b.packet[i] = i < ni ? _mm512_maskz_loadu_ps(first_lanes(nc), src + static_cast<size_t>(i0 + i) * cols + c0)
                             : _mm512_setzero_ps();
      Eigen::internal::ptranspose(b);
      for (int c = 0; c < nc; ++c)
        _mm512_mask_storeu_ps(dst + static_cast<size_t>(c0 + c) * rows + i0, first_lanes(ni), b.packet[c]);
    }
  }
}

#elif defined(__AVX2__) && defined(__FMA__)
namespace {

// The sums of four vectors: lane g of the result is the sum of the eight lanes of the g-th argument.
inline __m128 sum4(__m256 a, __m256 b, __m256 c, __m256 d) {
  const __m256 ab = _mm256_hadd_ps(a, b), cd = _mm256_hadd_ps(c, d);
  const __m256 z = _mm256_hadd_ps(ab, cd);  // [a b c d | a b c d], each half a partial sum
  return _mm_add_ps(_mm256_castps256_ps128(z), _mm256_extractf128_ps(z, 1));
}

// DH: floats per head (16 or 32), so DH / 8 vectors per head; heads in groups of four.
template <int DH>
void key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m, float* scores) {
  constexpr int HV = DH / 8;
  const int d = s.d();
  for (int j = 0; j < m; ++j) {
    const float* kr = k + static_cast<size_t>(keys[j]) * d;
    for (int h = 0; h < s.heads; h += 4) {
      __m256 acc[4];
      for (int g = 0; g < 4; ++g) {
        const int base = (h + g) * DH;
        acc[g] = _mm256_mul_ps(_mm256_loadu_ps(q + base), _mm256_loadu_ps(kr + base));
        for (int i = 1; i < HV; ++i)
          acc[g] = _mm256_fmadd_ps(_mm256_loadu_ps(q + base + 8 * i), _mm256_loadu_ps(kr + base + 8 * i), acc[g]);
      }
      alignas(16) float lanes[4];
      _mm_store_ps(lanes, sum4(acc[0], acc[1], acc[2], acc[3]));
      for (int g = 0; g < 4; ++g) scores[(h + g) * m + j] = lanes[g];
    }
  }
}

// Columns in blocks of 64 (eight accumulators); column c belongs to head c / DH.
template <int DH>
void weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m, float* out) {
  const int d = s.d();
  for (int c0 = 0; c0 < d; c0 += 64) {
    const int h0 = c0 / DH;
    __m256 acc[8];
    for (int i = 0; i < 8; ++i) acc[i] = _mm256_loadu_ps(out + c0 + 8 * i);
    for (int j = 0; j < m; ++j) {
      const float* vr = v + static_cast<size_t>(keys[j]) * d + c0;
      for (int i = 0; i < 8; ++i) {
        const __m256 w = _mm256_broadcast_ss(a + (h0 + 8 * i / DH) * m + j);
        acc[i] = _mm256_fmadd_ps(w, _mm256_loadu_ps(vr + 8 * i), acc[i]);
      }
    }
    for (int i = 0; i < 8; ++i) _mm256_storeu_ps(out + c0 + 8 * i, acc[i]);
  }
}

bool fast_shape(const AttentionShape& s) { return s.heads % 4 == 0 && (s.dh == 16 || s.dh == 32) && s.d() % 64 == 0; }

}  // namespace

void kernel_key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                       float* scores) {
  if (!fast_shape(s)) return kernel_key_scores_plain(s, q, k, keys, m, scores);
  if (s.dh == 32) return key_scores<32>(s, q, k, keys, m, scores);
  key_scores<16>(s, q, k, keys, m, scores);
}

void kernel_weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                            float* out) {
  if (!fast_shape(s)) return kernel_weighted_values_plain(s, a, v, keys, m, out);
  if (s.dh == 32) return weighted_values<32>(s, a, v, keys, m, out);
  weighted_values<16>(s, a, v, keys, m, out);
}

// Keys run eight to a vector (as the AVX-512 forms, half the width); keys past the last whole vector take the
// plain loop.
void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel_t, int m, float* scores,
                            int stride) {
  if (s.heads % 4 != 0) return kernel_relation_scores_plain(s, u, rel_t, m, scores, stride);
  const int r = s.r;
  for (int h = 0; h < s.heads; h += 4) {
    float* sh = scores + static_cast<size_t>(h) * stride;
    const float* uh = u + h * r;
    int j = 0;
    for (; j + 16 <= m; j += 16) {
      __m256 acc[8];
      for (int g = 0; g < 4; ++g) {
        acc[2 * g] = _mm256_loadu_ps(sh + g * stride + j);
        acc[2 * g + 1] = _mm256_loadu_ps(sh + g * stride + j + 8);
      }
      for (int c = 0; c < r; ++c) {
        const __m256 x0 = _mm256_loadu_ps(rel_t + c * m + j), x1 = _mm256_loadu_ps(rel_t + c * m + j + 8);
        for (int g = 0; g < 4; ++g) {
          const __m256 w = _mm256_broadcast_ss(uh + g * r + c);
          acc[2 * g] = _mm256_fmadd_ps(w, x0, acc[2 * g]);
          acc[2 * g + 1] = _mm256_fmadd_ps(w, x1, acc[2 * g + 1]);
        }
      }
      for (int g = 0; g < 4; ++g) {
        _mm256_storeu_ps(sh + g * stride + j, acc[2 * g]);
        _mm256_storeu_ps(sh + g * stride + j + 8, acc[2 * g + 1]);
      }
    }
    for (int g = 0; g < 4; ++g)
      for (int c = 0; c < r; ++c)
        for (int jj = j; jj < m; ++jj) sh[g * stride + jj] += uh[g * r + c] * rel_t[c * m + jj];
  }
}

void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel_t, int m, int stride,
                              float* out) {
  if (s.heads % 4 != 0 || s.r % 4 != 0)
    return kernel_weighted_relation_plain(s, a, rel_t, m, stride, out);
  const int r = s.r;
  const int whole = m - m % 8;
  for (int h = 0; h < s.heads; h += 4) {
    const float* ah = a + static_cast<size_t>(h) * stride;
    for (int c = 0; c < r; c += 4) {
      __m256 acc[16];
      for (int i = 0; i < 16; ++i) acc[i] = _mm256_setzero_ps();
      for (int j = 0; j < whole; j += 8) {
        __m256 w[4], x[4];
        for (int g = 0; g < 4; ++g) w[g] = _mm256_loadu_ps(ah + g * stride + j);
        for (int e = 0; e < 4; ++e) x[e] = _mm256_loadu_ps(rel_t + (c + e) * m + j);
        for (int g = 0; g < 4; ++g)
          for (int e = 0; e < 4; ++e) acc[4 * g + e] = _mm256_fmadd_ps(w[g], x[e], acc[4 * g + e]);
      }
      for (int g = 0; g < 4; ++g) {
        alignas(16) float sums[4];
        _mm_store_ps(sums, sum4(acc[4 * g], acc[4 * g + 1], acc[4 * g + 2], acc[4 * g + 3]));
        for (int e = 0; e < 4; ++e) {
          for (int j = whole; j < m; ++j) sums[e] += ah[g * stride + j] * rel_t[(c + e) * m + j];
          out[(h + g) * r + c + e] = sums[e];
        }
      }
    }
  }
}

namespace {

inline float hmax(__m256 x) {
  __m128 y = _mm_max_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
  y = _mm_max_ps(y, _mm_movehl_ps(y, y));
  y = _mm_max_ss(y, _mm_movehdup_ps(y));
  return _mm_cvtss_f32(y);
}

inline float hsum(__m256 x) {
  __m128 y = _mm_add_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
  y = _mm_add_ps(y, _mm_movehl_ps(y, y));
  y = _mm_add_ss(y, _mm_movehdup_ps(y));
  return _mm_cvtss_f32(y);
}

}  // namespace

void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale, float* inv_sums) {
  // Whole vectors, the last one masked (its empty lanes read as -inf, whose exp is 0): no scalar exp for a tail.
  const __m256 lowest = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
  const int full = cols / 8;
  const int rest = cols % 8;
  alignas(32) static constexpr int kLanes[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
  const __m256i tail = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kLanes + 8 - rest));
  const __m256 tail_f = _mm256_castsi256_ps(tail);
  auto load_tail = [&](const float* p) { return _mm256_blendv_ps(lowest, _mm256_maskload_ps(p, tail), tail_f); };
  for (int i = 0; i < rows; ++i) {
    float* row = s + static_cast<size_t>(i) * stride;
    __m256 top = lowest;
    for (int b = 0; b < full; ++b) top = _mm256_max_ps(top, _mm256_loadu_ps(row + 8 * b));
    if (rest) top = _mm256_max_ps(top, load_tail(row + 8 * full));
    const __m256 shift = _mm256_set1_ps(hmax(top));
    const __m256 k = _mm256_set1_ps(scale);
    __m256 sum = _mm256_setzero_ps();
    auto exp_at = [&](__m256 x) { return Eigen::internal::pexp(_mm256_mul_ps(_mm256_sub_ps(x, shift), k)); };
    for (int b = 0; b < full; ++b) {
      const __m256 e = exp_at(_mm256_loadu_ps(row + 8 * b));
      _mm256_storeu_ps(row + 8 * b, e);
      sum = _mm256_add_ps(sum, e);
    }
    if (rest) {
      const __m256 e = _mm256_and_ps(exp_at(load_tail(row + 8 * full)), tail_f);  // exp(-inf) may not be 0 here
      _mm256_maskstore_ps(row + 8 * full, tail, e);
      sum = _mm256_add_ps(sum, e);
    }
    const float inv_sum = 1.0f / hsum(sum);
    if (inv_sums) {
      inv_sums[i] = inv_sum;
      continue;
    }
    const __m256 inv = _mm256_set1_ps(inv_sum);
    for (int b = 0; b < full; ++b) _mm256_storeu_ps(row + 8 * b, _mm256_mul_ps(_mm256_loadu_ps(row + 8 * b), inv));
    if (rest)
      _mm256_maskstore_ps(row + 8 * full, tail, _mm256_mul_ps(_mm256_maskload_ps(row + 8 * full, tail), inv));
  }
}

void kernel_transpose(const float* src, int rows, int cols, float* dst) {
  kernel_transpose_plain(src, rows, cols, dst);
}

#else  // neither AVX-512 nor AVX2 with FMA: the plain forms

void kernel_key_scores(const AttentionShape& s, const float* q, const float* k, const int* keys, int m,
                       float* scores) {
  kernel_key_scores_plain(s, q, k, keys, m, scores);
}
void kernel_relation_scores(const AttentionShape& s, const float* u, const float* rel_t, int m, float* scores,
                            int stride) {
  kernel_relation_scores_plain(s, u, rel_t, m, scores, stride);
}
void kernel_weighted_values(const AttentionShape& s, const float* a, const float* v, const int* keys, int m,
                            float* out) {
  kernel_weighted_values_plain(s, a, v, keys, m, out);
}
void kernel_weighted_relation(const AttentionShape& s, const float* a, const float* rel_t, int m, int stride,
                              float* out) {
  kernel_weighted_relation_plain(s, a, rel_t, m, stride, out);
}
void kernel_softmax_rows(float* s, int rows, int cols, int stride, float scale, float* inv_sums) {
  kernel_softmax_rows_plain(s, rows, cols, stride, scale, inv_sums);
}

void kernel_transpose(const float* src, int rows, int cols, float* dst) {
  kernel_transpose_plain(src, rows, cols, dst);
}

#endif

}  // namespace ss
