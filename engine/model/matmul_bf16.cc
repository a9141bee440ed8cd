#include "engine/model/matmul_bf16.h"

#include <cpuid.h>
#include <immintrin.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>

namespace ss {
namespace {

constexpr int kTileRows = 16;   // rows of every tile used here
constexpr int kTileDepth = 32;  // bf16 values per A-tile row (64 bytes)

// The tile configuration of this kernel: tiles 0-3 accumulate a 32 x 32 block of y (fp32), 4-5 hold 32 rows of x,
// 6-7 hold 32 columns of W (bf16 pairs, the VNNI order the dot product reads).
struct alignas(64) TileConfig {
  uint8_t palette = 1, start_row = 0;
  uint8_t reserved[14] = {};
  uint16_t bytes_per_row[16] = {};
  uint8_t rows[16] = {};
};

TileConfig tile_config() {
  TileConfig c;
  for (int t = 0; t < 8; ++t) c.rows[t] = kTileRows, c.bytes_per_row[t] = 64;
  return c;
}

bool cpu_has_avx512_bf16() {
  unsigned a, b, c, d;
  if (!__get_cpuid_count(7, 0, &a, &b, &c, &d)) return false;
  const bool avx512f = b & (1u << 16);
  if (!__get_cpuid_count(7, 1, &a, &b, &c, &d)) return false;
  return avx512f && (a & (1u << 5));
}

bool cpu_has_amx_bf16() {  // the AMX kernel converts its inputs with AVX512-BF16, so it needs that too
  unsigned a, b, c, d;
  if (!__get_cpuid_count(7, 0, &a, &b, &c, &d)) return false;
  const bool amx_bf16 = d & (1u << 22), amx_tile = d & (1u << 24);
  return amx_bf16 && amx_tile && cpu_has_avx512_bf16();
}

// Linux keeps the 8 KB tile state off by default; a process asks for it once (ARCH_REQ_XCOMP_PERM, XTILEDATA).
bool request_tile_state() {
  constexpr long kArchReqXcompPerm = 0x1023, kXfeatureXtiledata = 18;
  return syscall(SYS_arch_prctl, kArchReqXcompPerm, kXfeatureXtiledata) == 0;
}

uint16_t to_bf16(float f) {  // round to nearest even, as vcvtne2ps2bf16 does (NaN stays NaN)
  uint32_t u;
  std::memcpy(&u, &f, 4);
  if ((u & 0x7fffffff) > 0x7f800000) return static_cast<uint16_t>((u >> 16) | 0x40);
  u += 0x7fff + ((u >> 16) & 1);
  return static_cast<uint16_t>(u >> 16);
}

}  // namespace

Bf16Kernel bf16_kernel() {
  static const Bf16Kernel k = cpu_has_amx_bf16() && request_tile_state() ? Bf16Kernel::amx
                              : cpu_has_avx512_bf16()                    ? Bf16Kernel::avx512_bf16
                                                                         : Bf16Kernel::none;
  return k;
}

const char* bf16_kernel_name(Bf16Kernel k) {
  return k == Bf16Kernel::amx ? "amx" : k == Bf16Kernel::avx512_bf16 ? "avx512-bf16" : "none";
}

bool bf16_products_available() { return bf16_kernel() != Bf16Kernel::none; }

bool bf16_packable(int out, int in) { return out > 0 && in > 0 && in % kTileDepth == 0; }

Bf16Weight bf16_pack(const float* w, int out, int in, long out_stride, long in_stride) {
  Bf16Weight p{out, in, {}};
  const int col_tiles = (out + 31) / 32 * 2, depth_tiles = (in + kTileDepth - 1) / kTileDepth;
  p.tiles.assign(static_cast<size_t>(col_tiles) * depth_tiles * kTileRows * kTileDepth, 0);
  for (int nt = 0; nt < col_tiles; ++nt)
    for (int kt = 0; kt < depth_tiles; ++kt) {
      uint16_t* tile = p.tiles.data() + (static_cast<size_t>(nt) * depth_tiles + kt) * kTileRows * kTileDepth;
      // Row r of a B tile holds, for each of its 16 outputs n, the pair W[n][2r], W[n][2r + 1] of its depth block.
      for (int r = 0; r < kTileRows; ++r)
        for (int n = 0; n < 16; ++n)
          for (int j = 0; j < 2; ++j) {
            const int o = nt * 16 + n, k = kt * kTileDepth + 2 * r + j;
            if (o < out && k < in) tile[r * kTileDepth + 2 * n + j] = to_bf16(w[o * out_stride + k * in_stride]);
          }
    }
  return p;
}

namespace {

constexpr int kChunkRows = 256;  // rows per call of linear_rows: bounds each thread's bf16 copy of x (<= 0.6 MB)

// x (rows x in) in bf16 into this thread's buffer, each row padded with zeros to `depth` (a multiple of 32) and the
// rows to a multiple of 32 (the AMX kernel's blocks). The padding rows hold whatever an earlier call left: they only
// feed output rows that are never stored.
__attribute__((target("avx512f,avx512bf16"))) const uint16_t* bf16_rows(const float* x, int rows, int in, int depth) {
  thread_local std::vector<uint16_t> a;
  const size_t padded_rows = (rows + 31) / 32 * 32;
  if (a.size() < padded_rows * depth) a.resize(padded_rows * depth);
  for (int i = 0; i < rows; ++i) {
    const float* xr = x + static_cast<size_t>(i) * in;
    uint16_t* ar = a.data() + static_cast<size_t>(i) * depth;
    for (int k = 0; k < depth; k += 32) {
      const int left = in - k;  // the last chunk loads only what is there; the rest reads as zeros
      const __mmask16 lo = left >= 16 ? 0xffff : (1u << std::max(left, 0)) - 1;
      const __mmask16 hi = left >= 32 ? 0xffff : left <= 16 ? 0 : (1u << (left - 16)) - 1;
      const __m512bh v = _mm512_cvtne2ps_pbh(_mm512_maskz_loadu_ps(hi, xr + k + 16), _mm512_maskz_loadu_ps(lo, xr + k));
      _mm512_storeu_si512(ar + k, reinterpret_cast<__m512i>(v));
    }
  }
  return a.data();
}

// bf16_linear for at most kChunkRows rows, on AMX tiles.
__attribute__((target("avx512f,avx512bf16,amx-tile,amx-bf16"))) void amx_rows(const float* x, int rows,
                                                                              const Bf16Weight& w, float* y) {
  const int in = w.in, out = w.out, depth_tiles = (in + kTileDepth - 1) / kTileDepth;
  const int depth = depth_tiles * kTileDepth;
  const uint16_t* const a = bf16_rows(x, rows, in, depth);
  static const TileConfig config = tile_config();
  _tile_loadconfig(&config);
  alignas(64) float edge[kTileRows * 16];
  const size_t a_stride = static_cast<size_t>(depth) * 2, tile_elems = kTileRows * kTileDepth;
  const uint16_t* b = w.tiles.data();
  for (int m0 = 0; m0 < rows; m0 += 32) {
    const bool two_rows = rows - m0 > kTileRows;  // a lone block of 16 rows (e.g. one token) does half the work
    const uint16_t* a0 = a + static_cast<size_t>(m0) * depth;
    const uint16_t* a1 = a0 + static_cast<size_t>(kTileRows) * depth;
    for (int n0 = 0; n0 < out; n0 += 32) {
      const uint16_t* b0 = b + static_cast<size_t>(n0 / 16) * depth_tiles * tile_elems;
      const uint16_t* b1 = b0 + depth_tiles * tile_elems;
      _tile_zero(0);
      _tile_zero(1);
      _tile_zero(2);
      _tile_zero(3);
      for (int kt = 0; kt < depth_tiles; ++kt) {
        _tile_loadd(4, a0 + kt * kTileDepth, a_stride);
        _tile_loadd(6, b0 + kt * tile_elems, 64);
        _tile_loadd(7, b1 + kt * tile_elems, 64);
        _tile_dpbf16ps(0, 4, 6);
        _tile_dpbf16ps(1, 4, 7);
        if (two_rows) {
          _tile_loadd(5, a1 + kt * kTileDepth, a_stride);
          _tile_dpbf16ps(2, 5, 6);
          _tile_dpbf16ps(3, 5, 7);
        }
      }
      // Tiles go straight to y when whole; an edge tile goes through `edge` and only its rows and columns inside y
      // are copied. (Tile numbers must be constants, hence the macro.)
#define SS_STORE_TILE(T, M, N)                                                                       \
  do {                                                                                               \
    if ((M) >= rows || (N) >= out) break;                                                            \
    if ((M) + kTileRows <= rows && (N) + 16 <= out) {                                                \
      _tile_stored(T, y + static_cast<size_t>(M) * out + (N), static_cast<size_t>(out) * 4);         \
      break;                                                                                         \
    }                                                                                                \
    _tile_stored(T, edge, 64);                                                                       \
    for (int i = 0; i < kTileRows && (M) + i < rows; ++i)                                            \
      std::copy_n(edge + i * 16, std::min(16, out - (N)), y + static_cast<size_t>((M) + i) * out + (N)); \
  } while (0)
      SS_STORE_TILE(0, m0, n0);
      SS_STORE_TILE(1, m0, n0 + 16);
      if (two_rows) {
        SS_STORE_TILE(2, m0 + kTileRows, n0);
        SS_STORE_TILE(3, m0 + kTileRows, n0 + 16);
      }
#undef SS_STORE_TILE
    }
  }
  _tile_release();  // back to the init state: a context switch need not save 8 KB of tiles
}

// A block of R rows of y by C column tiles (16 outputs each) with AVX512-BF16: for each depth pair, R x C `vdpbf16ps`
// of a row's pair (broadcast) by a B-tile row, which holds the pair of each of its 16 outputs: the packed tiles are
// already in the order this instruction reads, and a column tile's depth tiles follow one another, so depth pair p
// is at p * 32 in both. Each output sums its depth pairs in order whatever R and C are, so a row's bits do not
// depend on its batch. `pairs`: the depth pairs that hold data (the padding's zero pairs are skipped).
template <int R, int C>
__attribute__((target("avx512f,avx512bf16"))) inline void avx512_block(const uint16_t* a, size_t a_stride,
                                                                      const uint16_t* b, size_t b_stride, int pairs,
                                                                      float* y, size_t y_stride, int cols) {
  __m512 acc[R][C];
  for (int i = 0; i < R; ++i)
    for (int c = 0; c < C; ++c) acc[i][c] = _mm512_setzero_ps();
  for (int p = 0; p < pairs; ++p) {
    __m512bh bv[C];
    for (int c = 0; c < C; ++c) bv[c] = reinterpret_cast<__m512bh>(_mm512_loadu_si512(b + c * b_stride + p * 32));
    for (int i = 0; i < R; ++i) {
      int32_t pair;
      std::memcpy(&pair, a + i * a_stride + 2 * p, 4);
      const __m512bh av = reinterpret_cast<__m512bh>(_mm512_set1_epi32(pair));
      for (int c = 0; c < C; ++c) acc[i][c] = _mm512_dpbf16_ps(acc[i][c], av, bv[c]);
    }
  }
  for (int i = 0; i < R; ++i)
    for (int c = 0; c < C; ++c) {
      const int left = cols - c * 16;
      const __mmask16 m = left >= 16 ? 0xffff : (1u << left) - 1;
      _mm512_mask_storeu_ps(y + i * y_stride + c * 16, m, acc[i][c]);
    }
}

// Every row of y for one block of C column tiles: blocks of 16 / C rows, so that a narrow block still has 16
// independent sums in flight (4 rows of a narrow block, 4-8 sums, were too few to cover the instruction's latency:
// docs/performance.md), then blocks of 4, then the rest.
template <int C>
void avx512_columns(const uint16_t* a, size_t depth, int rows, const uint16_t* b, size_t tile_stride, int pairs,
                    float* y, int out, int cols) {
  constexpr int kRows = 16 / C;
  int m0 = 0;
  for (; m0 + kRows <= rows; m0 += kRows)
    avx512_block<kRows, C>(a + m0 * depth, depth, b, tile_stride, pairs, y + static_cast<size_t>(m0) * out, out, cols);
  if constexpr (kRows > 4)
    for (; m0 + 4 <= rows; m0 += 4)
      avx512_block<4, C>(a + m0 * depth, depth, b, tile_stride, pairs, y + static_cast<size_t>(m0) * out, out, cols);
  const uint16_t* at = a + m0 * depth;
  float* yt = y + static_cast<size_t>(m0) * out;
  switch (rows - m0) {
    case 3: avx512_block<3, C>(at, depth, b, tile_stride, pairs, yt, out, cols); break;
    case 2: avx512_block<2, C>(at, depth, b, tile_stride, pairs, yt, out, cols); break;
    case 1: avx512_block<1, C>(at, depth, b, tile_stride, pairs, yt, out, cols); break;
    default: break;
  }
}

// bf16_linear for at most kChunkRows rows with AVX512-BF16, for CPUs without AMX: column blocks of up to 4 tiles (64
// outputs), each over every row.
__attribute__((target("avx512f,avx512bf16"))) void avx512_rows(const float* x, int rows, const Bf16Weight& w,
                                                               float* y) {
  const int in = w.in, out = w.out, depth_tiles = (in + kTileDepth - 1) / kTileDepth, pairs = (in + 1) / 2;
  const size_t depth = static_cast<size_t>(depth_tiles) * kTileDepth, tile_stride = depth * kTileRows;
  const uint16_t* const a = bf16_rows(x, rows, in, static_cast<int>(depth));
  for (int n0 = 0; n0 < out; n0 += 64) {
    const uint16_t* b = w.tiles.data() + static_cast<size_t>(n0 / 16) * tile_stride;
    const int cols = std::min(64, out - n0);
    switch ((cols + 15) / 16) {
      case 4: avx512_columns<4>(a, depth, rows, b, tile_stride, pairs, y + n0, out, cols); break;
      case 3: avx512_columns<3>(a, depth, rows, b, tile_stride, pairs, y + n0, out, cols); break;
      case 2: avx512_columns<2>(a, depth, rows, b, tile_stride, pairs, y + n0, out, cols); break;
      default: avx512_columns<1>(a, depth, rows, b, tile_stride, pairs, y + n0, out, cols); break;
    }
  }
}

}  // namespace

void bf16_linear(const float* x, int rows, const Bf16Weight& w, float* y) { bf16_linear(x, rows, w, y, bf16_kernel()); }

void bf16_linear(const float* x, int rows, const Bf16Weight& w, float* y, Bf16Kernel kernel) {
  const auto kernel_rows = kernel == Bf16Kernel::amx ? amx_rows : avx512_rows;
  // Rows are independent, so chunks give the same bits as one call.
  for (int r = 0; r < rows; r += kChunkRows)
    kernel_rows(x + static_cast<size_t>(r) * w.in, std::min(kChunkRows, rows - r), w,
                y + static_cast<size_t>(r) * w.out);
}

}  // namespace ss
