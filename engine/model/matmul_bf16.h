// Dense products in bf16: y = x W^T with x and W rounded to bf16 (round to nearest even) and every sum in fp32. For
// the model's Linear layers when ModelOptions::matmul_precision is bf16 (docs/performance.md). Two kernels read the same
// packed weights: Intel AMX tiles, and AVX512-BF16's `vdpbf16ps` where the CPU has no AMX (AMD Zen 4 and 5). They
// sum each output's pairs in another order, so their bits differ in the last place; each is deterministic. The
// kernels alone are compiled for their instructions (function target attributes, not file flags: a template
// instantiated in a file built with wider flags could be the copy the linker keeps for every other file too), and
// run only where the CPU has them (checked at run time).
#pragma once

#include <cstdint>
#include <vector>

namespace ss {

struct Bf16Weight {
  int out = 0, in = 0;          // W's shape [out, in]
  std::vector<uint16_t> tiles;  // W in AMX B-tile order, which is also vdpbf16ps's: [out padded to 32 / 16][in
                                // padded to 32 / 32] tiles of 16 x 32 bf16, zeros in the padding
};

enum class Bf16Kernel { none, avx512_bf16, amx };  // in order of speed; a CPU with one has those before it
// The fastest kernel this CPU has: AMX where it has AMX-BF16 and AVX512-BF16 and Linux lets this process use the
// tile registers, else AVX512-BF16 where it has that, else none.
Bf16Kernel bf16_kernel();
const char* bf16_kernel_name(Bf16Kernel k);  // "amx", "avx512-bf16", "none"
bool bf16_products_available();              // bf16_kernel() != none
// Whether a Linear layer's [out, in] weight runs in bf16: `in` a multiple of 32 (a tile's depth), which every product
// over the model width is; the few narrower ones (relation features, point features) stay fp32.
bool bf16_packable(int out, int in);
// W [out, in] with W[o][k] = w[o * out_stride + k * in_stride] (row-major: in, 1; a transposed view: 1, out).
Bf16Weight bf16_pack(const float* w, int out, int in, long out_stride, long in_stride);
inline Bf16Weight bf16_pack(const float* w, int out, int in) { return bf16_pack(w, out, in, in, 1); }
// y (rows x w.out, row-major) = x (rows x w.in, row-major) W^T. Each row of y depends on its own row of x only, so
// a row's bits do not depend on the batch it is computed in. Requires bf16_products_available.
void bf16_linear(const float* x, int rows, const Bf16Weight& w, float* y);
// The same with a kernel named (tests and benchmarks): one the CPU has, at most bf16_kernel().
void bf16_linear(const float* x, int rows, const Bf16Weight& w, float* y, Bf16Kernel kernel);

}  // namespace ss
