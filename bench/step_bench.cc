// Session step latency by agent count (large model, 16 lights, one thread), and the incremental decoder against a
// full recompute at step 19. Run: build/bench/step_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>

#include "common/bench_world.h"
#include "engine/model/linalg.h"

namespace ss {
namespace {

const BenchWorld& world() {
  static const BenchWorld* w = [] {
    enable_flush_to_zero();
    auto made = make_bench_world(SS_DATA_DIR "/womd/tfrecord/motion_data_one_scenario.tfrecord", "large");
    if (!made.ok()) {
      std::fprintf(stderr, "step_bench: %s\n", std::string(made.status().message()).c_str());
      std::exit(1);
    }
    return new BenchWorld(std::move(*made));
  }();
  return *w;
}

void BM_Step(benchmark::State& state) {
  const int agents = static_cast<int>(state.range(0));
  auto s = bench_session(world(), agents, 1);
  if (!s.ok()) return state.SkipWithError(std::string(s.status().message()).c_str());
  for (int i = 0; i < world().model->config().window_steps; ++i) (void)(*s)->step({});  // fill the cache window
  for (auto _ : state) benchmark::DoNotOptimize((*s)->step({}));
  state.counters["agents"] = agents;
}
BENCHMARK(BM_Step)->Arg(16)->Arg(32)->Arg(64)->Arg(128)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_Step19(benchmark::State& state, bool full) {
  static const HistoryBatches h = *history_batches(world(), 64, 19);
  const Model& m = *world().model;
  for (auto _ : state) {
    state.PauseTiming();
    KvCache cache = m.new_cache();
    std::vector<DecoderToken> all;
    for (const auto& b : h.before) {
      std::vector<DecoderToken> t = b;
      if (full) all.insert(all.end(), t.begin(), t.end());
      else m.decode(*world().map, cache, t);
    }
    state.ResumeTiming();
    if (full) {
      for (const auto& b : h.at) all.insert(all.end(), b.begin(), b.end());
      benchmark::DoNotOptimize(m.decode_full(*world().map, all));
    } else {
      for (const auto& b : h.at) {
        std::vector<DecoderToken> t = b;
        benchmark::DoNotOptimize(m.decode(*world().map, cache, t));
      }
    }
  }
}
BENCHMARK_CAPTURE(BM_Step19, incremental, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Step19, full_recompute, true)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ss

BENCHMARK_MAIN();
