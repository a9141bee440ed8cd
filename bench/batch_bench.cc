// Would batching sessions pay? The dense products of one 64-agent step of the large model (340 tokens) against the
// same products over the tokens of 4 and 32 sessions' steps stacked, with each kernel the engine has (Eigen fp32;
// bf16 with AVX512-BF16, and on AMX): a batch pays only if its cost per row falls, and the kernels compare by their
// per_row counters. Shapes: the Linear layers of the large model (d_model 128,
// feed-forward 512) and of the small one the server ships (64, 256). Run: build/bench/batch_bench; compare the
// per_row counters across the first argument.
#include <benchmark/benchmark.h>

#include "engine/model/linalg.h"
#include "engine/model/matmul_bf16.h"

namespace ss {
namespace {

constexpr int kStepRows = 340;  // one 64-agent step's new tokens (338 in bench/step_bench's BM_Step19)

// Arguments: sessions stacked (1, 4, 32), output width, input width. The product alone, into an output allocated
// once: the best case for a batch (a batching server would also gather each session's rows and scatter them back).
// `kernel` none: Eigen's fp32 product.
void BM_Linear(benchmark::State& state, Bf16Kernel kernel) {
  const bool bf16 = kernel != Bf16Kernel::none;
  if (bf16_kernel() < kernel) return state.SkipWithError("this CPU lacks that kernel's instructions");
  const int rows = kStepRows * static_cast<int>(state.range(0));
  const int out = static_cast<int>(state.range(1)), in = static_cast<int>(state.range(2));
  const Mat w = Mat::Random(out, in) * 0.1f;
  const Bf16Weight packed = bf16 ? bf16_pack(w.data(), out, in) : Bf16Weight{};
  const Mat x = Mat::Random(rows, in);
  Mat y(rows, out);
  for (auto _ : state) {
    if (bf16) bf16_linear(x.data(), rows, packed, y.data(), kernel);
    else y.noalias() = x * w.transpose();
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["rows"] = rows;
  // Seconds per row (printed with an SI prefix: 38n is 38 ns).
  state.counters["per_row"] = benchmark::Counter(
      static_cast<double>(rows), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void shapes(benchmark::internal::Benchmark* b) {
  for (int sessions : {1, 4, 32})
    for (auto [out, in] : {std::pair{128, 128}, {512, 128}, {128, 512}, {64, 64}, {256, 64}, {64, 256}})
      b->Args({sessions, out, in});
  // The queries that read the whole map (1,093 keys) together, per head: scores (out: the keys; in: the head width,
  // 32 large, 16 small) and weighted values (out: the head width; in: the keys).
  for (auto [out, in] : {std::pair{1093, 32}, {1093, 16}, {32, 1093}, {16, 1093}}) b->Args({1, out, in});
}

BENCHMARK_CAPTURE(BM_Linear, fp32, Bf16Kernel::none)->Apply(shapes)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Linear, bf16_avx512, Bf16Kernel::avx512_bf16)->Apply(shapes)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_Linear, bf16_amx, Bf16Kernel::amx)->Apply(shapes)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace ss

BENCHMARK_MAIN();
