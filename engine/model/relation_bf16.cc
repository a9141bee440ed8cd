#include "engine/model/relation_bf16.h"

#include <immintrin.h>

#include <cstdint>
#include <cstring>

#include "engine/model/matmul_bf16.h"
#include "engine/model/vocab.h"

namespace ss {
namespace {

constexpr int kMaxWidth = 256;  // the widest first layer kept in registers and on the stack (relation_dim is 32)

// Sixteen pairs at a time, one to a lane: the features gathered, the first layer's outputs two at a time rounded to
// bf16 pairs (each lane holding output 2c low and 2c + 1 high, the order vdpbf16ps reads a depth pair in), then
// eight outputs of the second layer at a time, each over the depth pairs in order, with W2's pair broadcast from the
// packed tiles (bf16_pack: tile (o / 16, p / 16), row p % 16, column pair o % 16).
__attribute__((target("avx512f,avx512bw,avx512bf16"))) void columns(const float* f, int n, const LinearParams& fc1,
                                                                   const LinearParams& fc2, float* out) {
  const int r1 = fc1.out, r = fc2.out, pairs = r1 / 2, depth_tiles = r1 / 32;
  const __m512 zero = _mm512_setzero_ps();
  const __m512i lane_offsets = _mm512_mullo_epi32(
      _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15), _mm512_set1_epi32(kRelationFeatures));
  alignas(64) static const uint16_t kInterleave[32] = {0, 16, 1, 17, 2,  18, 3,  19, 4,  20, 5,  21, 6,  22, 7,  23,
                                                       8, 24, 9, 25, 10, 26, 11, 27, 12, 28, 13, 29, 14, 30, 15, 31};
  const __m512i interleave = _mm512_load_si512(kInterleave);
  const uint16_t* tiles = fc2.bf16->tiles.data();
  __m512bh h[kMaxWidth / 2];
  for (int j0 = 0; j0 < n; j0 += 16) {
    const __mmask16 m = n - j0 >= 16 ? __mmask16(0xffff) : static_cast<__mmask16>((1u << (n - j0)) - 1);
    const float* fj = f + static_cast<size_t>(j0) * kRelationFeatures;
    __m512 x[kRelationFeatures];
    for (int k = 0; k < kRelationFeatures; ++k) x[k] = _mm512_mask_i32gather_ps(zero, m, lane_offsets, fj + k, 4);
    for (int c = 0; c < r1; c += 2) {
      __m512 a[2];
      for (int e = 0; e < 2; ++e) {
        const float* w = fc1.weight + static_cast<size_t>(c + e) * kRelationFeatures;
        __m512 acc = zero;
        for (int k = 0; k < kRelationFeatures; ++k) acc = _mm512_fmadd_ps(x[k], _mm512_set1_ps(w[k]), acc);
        a[e] = _mm512_max_ps(_mm512_add_ps(acc, _mm512_set1_ps(fc1.bias[c + e])), zero);
      }
      h[c / 2] = reinterpret_cast<__m512bh>(
          _mm512_permutexvar_epi16(interleave, reinterpret_cast<__m512i>(_mm512_cvtne2ps_pbh(a[1], a[0]))));
    }
    for (int o0 = 0; o0 < r; o0 += 8) {
      __m512 acc[8];
      for (int i = 0; i < 8; ++i) acc[i] = zero;
      for (int p = 0; p < pairs; ++p) {
        const uint16_t* row = tiles + (static_cast<size_t>(p / 16) * 16 + p % 16) * 32;
        for (int i = 0; i < 8; ++i) {
          const int o = o0 + i;
          int32_t pair;
          std::memcpy(&pair, row + static_cast<size_t>(o / 16) * depth_tiles * 16 * 32 + 2 * (o % 16), 4);
          acc[i] = _mm512_dpbf16_ps(acc[i], h[p], reinterpret_cast<__m512bh>(_mm512_set1_epi32(pair)));
        }
      }
      for (int i = 0; i < 8; ++i) {
        const __m512 y = _mm512_max_ps(_mm512_add_ps(acc[i], _mm512_set1_ps(fc2.bias[o0 + i])), zero);
        _mm512_mask_storeu_ps(out + static_cast<size_t>(o0 + i) * n + j0, m, y);
      }
    }
  }
}

}  // namespace

bool relation_columns_bf16_fits(const LinearParams& fc1, const LinearParams& fc2) {
  return fc2.bf16 != nullptr && bf16_kernel() != Bf16Kernel::none && fc1.in == kRelationFeatures &&
         fc1.out % 32 == 0 && fc1.out <= kMaxWidth && fc2.in == fc1.out && fc2.out % 8 == 0 && fc1.bias != nullptr &&
         fc2.bias != nullptr;
}

void relation_columns_bf16(const float* f, int n, const LinearParams& fc1, const LinearParams& fc2, float* out) {
  columns(f, n, fc1, fc2, out);
}

}  // namespace ss
