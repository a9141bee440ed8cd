// The self-attention relation columns of one busy decode call (17,600 pairs: 400 key sets of 44, or 137 of 128 as a
// map's), fused (engine/model/relation_bf16.h) against the AVX512-BF16 product path it replaced in bf16 mode (sets in
// chunks of about 2,048 rows through relation_embedding, then each set's block transposed). Random weights and
// features, relation_dim 32 (both configurations'). Both paths give the same bits (checked before timing). Needs
// AVX512-BF16; elsewhere it reports an error and times nothing.
#include <benchmark/benchmark.h>

#include <cstring>
#include <random>
#include <vector>

#include "engine/model/attention.h"
#include "engine/model/attention_kernels.h"
#include "engine/model/matmul_bf16.h"
#include "engine/model/relation_bf16.h"
#include "engine/model/vocab.h"

namespace ss {
namespace {

constexpr int kPairs = 17600, kR = 32;

struct World {
  std::vector<float> w1, b1, w2, b2;
  Bf16Weight w2_bf16;
  RelationParams p;
  std::vector<std::vector<float>> features;  // per set
  std::vector<Mat> out;

  explicit World(int n) {
    std::mt19937 rng(1);
    std::normal_distribution<float> g(0, 0.5f);
    auto fill = [&](std::vector<float>& v, size_t size) {
      v.resize(size);
      for (float& x : v) x = g(rng);
    };
    fill(w1, kR * kRelationFeatures);
    fill(b1, kR);
    fill(w2, kR * kR);
    fill(b2, kR);
    w2_bf16 = bf16_pack(w2.data(), kR, kR);
    p = {{w1.data(), b1.data(), kR, kRelationFeatures, nullptr}, {w2.data(), b2.data(), kR, kR, &w2_bf16}};
    features.resize(kPairs / n);
    for (auto& f : features) fill(f, static_cast<size_t>(n) * kRelationFeatures);
    out.resize(features.size());
  }
  int n(size_t set) const { return static_cast<int>(features[set].size()) / kRelationFeatures; }

  void fused() {
    for (size_t i = 0; i < features.size(); ++i) {
      out[i].resize(kR, n(i));
      relation_columns_bf16(features[i].data(), n(i), p.fc1, p.fc2, out[i].data());
    }
  }
  void products() {
    Mat chunk;
    for (size_t first = 0; first < features.size();) {
      size_t last = first;
      int rows = 0;
      while (last < features.size() && (last == first || rows + n(last) <= 2048)) rows += n(last++);
      chunk.resize(rows, kRelationFeatures);
      float* at = chunk.data();
      for (size_t i = first; i < last; ++i) at = std::copy(features[i].begin(), features[i].end(), at);
      const Mat h = relation_embedding(chunk, p);
      for (size_t i = first, row = 0; i < last; row += n(i), ++i) {
        out[i].resize(kR, n(i));
        kernel_transpose(h.data() + row * kR, n(i), kR, out[i].data());
      }
      first = last;
    }
  }
};

void run(benchmark::State& state, bool fused) {
  if (!bf16_products_available()) {
    state.SkipWithError("this CPU has no AVX512-BF16");
    return;
  }
  World w(static_cast<int>(state.range(0)));
  w.products();
  const std::vector<Mat> want = w.out;
  w.fused();
  // The fused pass gives the products' bits where they run on AVX512-BF16; AMX's tiles add in another order.
  for (size_t i = 0; i < want.size() && bf16_kernel() == Bf16Kernel::avx512_bf16; ++i)
    if (std::memcmp(want[i].data(), w.out[i].data(), want[i].size() * sizeof(float)) != 0) {
      state.SkipWithError("the fused columns differ from the products'");
      return;
    }
  for (auto _ : state) {
    if (fused) w.fused();
    else w.products();
    benchmark::DoNotOptimize(w.out.back().data());
  }
  state.SetItemsProcessed(state.iterations() * kPairs);  // pairs per second
}

void BM_RelationColumnsProducts(benchmark::State& state) { run(state, false); }
void BM_RelationColumnsFused(benchmark::State& state) { run(state, true); }
BENCHMARK(BM_RelationColumnsProducts)->Arg(44)->Arg(128)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RelationColumnsFused)->Arg(44)->Arg(128)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace ss

BENCHMARK_MAIN();
