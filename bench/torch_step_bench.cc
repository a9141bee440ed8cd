// The engine against the same model in libtorch (the trainer's model stepped incrementally over its own cache), at
// 64 agents and 16 lights on the real scenario, one thread each, in one run: the decoder batches of step 19 over a
// cache of the steps before. Run: build/bench/torch_step_bench; the ratio of the two times is docs/performance.md's figure.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>

#include "common/bench_world.h"
#include "engine/model/linalg.h"
#include "training/incremental.h"

namespace ss {
namespace {

constexpr int kAgents = 64, kStep = 19;

struct World {
  BenchWorld w;
  HistoryBatches h;
  std::unique_ptr<train::TorchModel> torch_model;
};

const World& world() {
  static const World* w = [] {
    enable_flush_to_zero();
    at::set_num_threads(1);
    at::globalContext().setFlushDenormal(true);
    auto made = make_bench_world(SS_DATA_DIR "/womd/tfrecord/motion_data_one_scenario.tfrecord",
                                 std::getenv("SS_BENCH_MODEL") ? std::getenv("SS_BENCH_MODEL") : "large");
    if (!made.ok()) {
      std::fprintf(stderr, "torch_step_bench: %s\n", std::string(made.status().message()).c_str());
      std::exit(1);
    }
    auto h = history_batches(*made, kAgents, kStep);
    if (!h.ok()) std::exit(1);
    auto* out = new World{std::move(*made), std::move(*h), nullptr};
    out->torch_model = std::make_unique<train::TorchModel>(out->w.model->weights());
    return out;
  }();
  return *w;
}

void BM_EngineStep(benchmark::State& state) {
  const World& w = world();
  const Model& m = *w.w.model;
  int64_t tokens = 0;
  for (auto _ : state) {
    state.PauseTiming();
    KvCache cache = m.new_cache();
    for (auto b : w.h.before) {
      cache.evict_before(b.front().step - m.config().window_steps + 1);
      m.decode(*w.w.map, cache, b);
    }
    state.ResumeTiming();
    for (auto b : w.h.at) {
      cache.evict_before(b.front().step - m.config().window_steps + 1);
      tokens += b.size();
      benchmark::DoNotOptimize(m.decode(*w.w.map, cache, b));
    }
  }
  state.counters["tokens_per_step"] = static_cast<double>(tokens) / state.iterations();
}
BENCHMARK(BM_EngineStep)->Unit(benchmark::kMillisecond)->MinTime(3.0);

void BM_TorchStep(benchmark::State& state) {
  const World& w = world();
  for (auto _ : state) {
    state.PauseTiming();
    train::TorchDecoder decoder(*w.torch_model, w.w.map->segments);
    for (auto b : w.h.before) decoder.decode(b);
    state.ResumeTiming();
    for (auto b : w.h.at) benchmark::DoNotOptimize(decoder.decode(b));
  }
}
BENCHMARK(BM_TorchStep)->Unit(benchmark::kMillisecond)->MinTime(3.0);

}  // namespace
}  // namespace ss

BENCHMARK_MAIN();
