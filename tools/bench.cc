// scenestreamer bench [--json] [--model W] [--scenario FILE] [--long-steps N] [--kv-precision fp32|fp16]
// The engine's speed and memory figures, measured in one run: step latency by agent count, the incremental decoder
// against a full recompute at step 19, session memory after a long rollout, KV bytes per token.
#include <algorithm>
#include <chrono>
#include <cstdio>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "common/bench_world.h"
#include "engine/io/json_text.h"
#include "engine/model/linalg.h"
#include "engine/model/matmul_bf16.h"
#include "nlohmann/json.hpp"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/shared_flags.h"

// bench_: simulate's --model, --scenario and --steps have other defaults.
ABSL_FLAG(std::string, bench_model, "large", "large or small (random weights of that configuration), or a weight file");
ABSL_FLAG(std::string, bench_scenario, ss::kBenchScenario, "the scenario file the sessions run on");
ABSL_FLAG(int, bench_steps, 30, "timed steps per agent count, at least 1");
ABSL_FLAG(int, long_steps, 1000, "steps of the long rollout whose session memory is measured, at least 1");

namespace ss::cli {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const double pos = p * (v.size() - 1);
  const size_t lo = static_cast<size_t>(pos);
  return lo + 1 < v.size() ? v[lo] + (pos - lo) * (v[lo + 1] - v[lo]) : v[lo];
}

// The dense-product rate, in the model's precision, on the shape of a 64-agent step's feed-forward layer (340 tokens,
// 128 -> 512), in this run: Eigen's fp32 GEMM, or the bf16 product (AMX or AVX512-BF16). The rate the dense part of
// a step can reach at best on this machine.
double gemm_gflops(MatmulPrecision precision) {
  const Mat x = Mat::Random(340, 128), w = Mat::Random(512, 128);
  const Bf16Weight packed = precision == MatmulPrecision::bf16 ? bf16_pack(w.data(), 512, 128) : Bf16Weight{};
  Mat y(340, 512);
  int reps = 0;
  const auto t0 = Clock::now();
  do {
    if (precision == MatmulPrecision::bf16) bf16_linear(x.data(), 340, packed, y.data());
    else y.noalias() = x * w.transpose();
    ++reps;
  } while (ms_since(t0) < 300);
  return 2.0 * x.rows() * x.cols() * w.rows() * reps / (ms_since(t0) * 1e6);
}

int fail(const absl::Status& st) {
  spdlog::error("bench: {}", std::string(st.message()));
  return 1;
}

}  // namespace

int bench_main(int argc, char** argv) {
  const Command command{"scenestreamer bench",
                        "usage: scenestreamer bench [--json] [--model large|small|WEIGHTS] [--scenario FILE] [--steps N]\n"
                        "                           [--long-steps N] [--kv-precision fp32|fp16] [--matmul-precision fp32|bf16]\n"
                        "                           [--motion-reject=false]\n"
                        "  Step latency by agent count, the incremental decoder against a full recompute at step 19,\n"
                        "  session memory after a long rollout, KV bytes per token; one thread.\n",
                        __FILE__,
                        {flag(FLAGS_json), flag(FLAGS_motion_reject), flag(FLAGS_kv_precision), flag(FLAGS_matmul_precision)}};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  const int steps = absl::GetFlag(FLAGS_bench_steps), long_steps = absl::GetFlag(FLAGS_long_steps);
  if (steps < 1) return usage_error(command, "--steps must be at least 1");
  if (long_steps < 1) return usage_error(command, "--long-steps must be at least 1");
  EngineOptions options;
  set_precisions(options);
  enable_flush_to_zero();
  auto world = make_bench_world(absl::GetFlag(FLAGS_bench_scenario), absl::GetFlag(FLAGS_bench_model), 16, options);
  if (!world.ok()) return fail(world.status());
  const ModelConfig& c = world->model->config();
  const bool json = absl::GetFlag(FLAGS_json);
  nlohmann::ordered_json out;
  out["model"] = c.name;
  out["threads"] = 1;
  out["kv_precision"] = kv_precision_name(world->model->kv_precision());
  out["matmul_precision"] = matmul_precision_name(world->model->matmul_precision());
  if (world->model->matmul_precision() == MatmulPrecision::bf16) out["bf16_kernel"] = bf16_kernel_name(bf16_kernel());
  out["lights"] = world->scenario->signals.empty() ? 0 : world->scenario->signals[world->scenario->current_time_index].size();
  out["map_segments"] = world->map->size();

  const double peak = gemm_gflops(world->model->matmul_precision());
  out["gemm_gflops"] = peak;  // in the model's precision: the floor below is that of the products the step runs

  // Step latency, after the cache window has filled; the work of the timed steps as counted by the decoder.
  struct Timed {
    std::vector<double> ms;
    double gflop = 0;  // per step
  };
  auto time_steps = [&](const BenchWorld& w, int agents) -> absl::StatusOr<Timed> {
    auto s = bench_session(w, agents, 1, nullptr, absl::GetFlag(FLAGS_motion_reject));
    if (!s.ok()) return s.status();
    for (int i = 0; i < c.window_steps; ++i)
      if (auto r = (*s)->step({}); !r.ok()) return r.status();
    Timed t;
    const double flops_before = w.model->decode_flops((*s)->decode_work());
    for (int i = 0; i < steps; ++i) {
      const auto t0 = Clock::now();
      if (auto r = (*s)->step({}); !r.ok()) return r.status();
      t.ms.push_back(ms_since(t0));
    }
    t.gflop = (w.model->decode_flops((*s)->decode_work()) - flops_before) / steps / 1e9;
    return t;
  };
  nlohmann::ordered_json p50, p99, gflop, achieved, floor_ms;
  for (int agents : {16, 32, 64, 128}) {
    auto timed = time_steps(*world, agents);
    if (!timed.ok()) return fail(timed.status());
    const std::vector<double>& ms = timed->ms;
    const double step_gflop = timed->gflop;
    double total_ms = 0;
    for (double m : ms) total_ms += m;
    const std::string key = std::to_string(agents);
    p50[key] = percentile(ms, 0.5);
    p99[key] = percentile(ms, 0.99);
    gflop[key] = step_gflop;
    achieved[key] = step_gflop * steps / (total_ms / 1e3);
    floor_ms[key] = step_gflop / peak * 1e3;
    if (!json)
      std::printf("step, %3d agents: p50 %.1f ms, p99 %.1f ms; %.3f GFLOP per step, %.1f GFLOP/s; %.1f ms at the GEMM peak\n",
                  agents, percentile(ms, 0.5), percentile(ms, 0.99), step_gflop, achieved[key].get<double>(),
                  floor_ms[key].get<double>());
  }
  out["step_ms_p50"] = p50;
  out["step_ms_p99"] = p99;
  // The decoder's counted work per step, the rate achieved, and the time that work would take at gemm_gflops.
  out["step_gflop"] = gflop;
  out["step_gflops_achieved"] = achieved;
  out["step_ms_at_gemm_peak"] = floor_ms;

  // A lone session's step with two threads (EngineOptions::step_threads): the same session, the same bits.
  EngineOptions two = options;
  two.step_threads = 2;
  auto world2 = make_bench_world(absl::GetFlag(FLAGS_bench_scenario), absl::GetFlag(FLAGS_bench_model), 16, two);
  if (!world2.ok()) return fail(world2.status());
  auto timed2 = time_steps(*world2, 64);
  if (!timed2.ok()) return fail(timed2.status());
  out["step_ms_p50_2_threads"] = {{"64", percentile(timed2->ms, 0.5)}};
  out["step_2_threads_speedup"] = {{"64", p50["64"].get<double>() / percentile(timed2->ms, 0.5)}};
  if (!json)
    std::printf("step, 64 agents, 2 threads: p50 %.1f ms (%.2fx one thread)\n", percentile(timed2->ms, 0.5),
                out["step_2_threads_speedup"]["64"].get<double>());

  // Step 19 of a 64-agent rollout: its new tokens over the cache, against the whole history recomputed.
  auto h = history_batches(*world, 64, 19);
  if (!h.ok()) return fail(h.status());
  std::vector<double> inc, full;
  for (int rep = 0; rep < 5; ++rep) {
    KvCache cache = world->model->new_cache();
    std::vector<DecoderToken> all;
    for (auto b : h->before) {
      all.insert(all.end(), b.begin(), b.end());
      world->model->decode(*world->map, cache, b);
    }
    auto t0 = Clock::now();
    for (auto b : h->at) {
      all.insert(all.end(), b.begin(), b.end());
      world->model->decode(*world->map, cache, b);
    }
    inc.push_back(ms_since(t0));
    t0 = Clock::now();
    world->model->decode_full(*world->map, all);
    full.push_back(ms_since(t0));
  }
  const double inc_ms = percentile(inc, 0.5), full_ms = percentile(full, 0.5);
  out["step19_incremental_ms"] = inc_ms;
  out["step19_full_recompute_ms"] = full_ms;
  out["cached_vs_full_ratio"] = full_ms / inc_ms;
  if (!json)
    std::printf("step 19, 64 agents: incremental %.1f ms, full recompute %.1f ms: %.1fx\n", inc_ms, full_ms, full_ms / inc_ms);

  // Memory of a 64-agent session over a long rollout: flat once the window is full.
  auto s = bench_session(*world, 64, 2, nullptr, absl::GetFlag(FLAGS_motion_reject));
  if (!s.ok()) return fail(s.status());
  size_t after_window = 0;
  for (int i = 0; i < long_steps; ++i) {
    if (auto r = (*s)->step({}); !r.ok()) return fail(r.status());
    if (i + 1 == 2 * c.window_steps) after_window = (*s)->memory_bytes();
  }
  out["session_bytes_after_window"] = after_window;
  out[absl::StrCat("session_bytes_after_", long_steps, "_steps")] = (*s)->memory_bytes();
  if (long_steps != 1000) out["session_bytes_after_1000_steps"] = nullptr;  // not measured in this run
  out["session_cache_tokens"] = (*s)->cache_tokens();
  out["kv_bytes_per_token"] =
      2 * c.decoder_layers * c.d_model * (world->model->kv_precision() == KvPrecision::fp16 ? sizeof(uint16_t) : sizeof(float));
  out["map_bytes_shared"] = world->map->bytes();
  if (json) {
    std::puts(json_text(out).c_str());
  } else {
    std::printf("64-agent session: %zu bytes after %d steps, %zu after %d steps (%zu cached tokens)\n", after_window,
                2 * c.window_steps, (*s)->memory_bytes(), long_steps, (*s)->cache_tokens());
    std::printf("KV bytes per token: %d; shared map encoding: %zu bytes\n", out["kv_bytes_per_token"].get<int>(),
                world->map->bytes());
  }
  return 0;
}

}  // namespace ss::cli
