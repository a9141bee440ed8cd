// scenestreamer bench [--json] [--model W] [--scenario FILE] [--long-steps N] [--kv-precision fp32|fp16]
// The engine's speed and memory figures, measured in one run: step latency by agent count, the incremental decoder
// against a full recompute at step 19, session memory after a long rollout, KV bytes per token.
#include <algorithm>
#include <chrono>
#include <cstdio>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "bench/bench_world.h"
#include "engine/io/json_text.h"
#include "engine/model/linalg.h"
#include "nlohmann/json.hpp"
#include "tools/cli_args.h"
#include "tools/commands.h"

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

// Eigen's matrix product on a decoder shape (a step's ~340 tokens through the feed-forward's first layer), in this
// run: the rate the dense part of a step can reach at best on this machine.
double gemm_gflops() {
  const Mat x = Mat::Random(340, 128), w = Mat::Random(512, 128);
  Mat y;
  int reps = 0;
  const auto t0 = Clock::now();
  do {
    y.noalias() = x * w.transpose();
    ++reps;
  } while (ms_since(t0) < 300);
  return 2.0 * x.rows() * x.cols() * w.rows() * reps / (ms_since(t0) * 1e6);
}

int fail(const absl::Status& st) {
  std::fprintf(stderr, "bench: %s\n", std::string(st.message()).c_str());
  return 1;
}

}  // namespace

int bench_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1, {"model", "scenario", "long-steps", "steps", "kv-precision"}, {"json", "help"});
  if (!args.ok() || args->has("help") || !args->positional.empty()) {
    if (!args.ok()) std::fprintf(stderr, "bench: %s\n", std::string(args.status().message()).c_str());
    std::fputs("usage: scenestreamer bench [--json] [--model large|small|WEIGHTS] [--scenario FILE]\n"
               "                           [--steps N (timed per agent count, default 30)] [--long-steps N (default 1000)]\n"
               "                           [--kv-precision fp32|fp16 (default: $SCENESTREAMER_KV_PRECISION, else fp32)]\n",
               args.ok() && args->has("help") ? stdout : stderr);
    return args.ok() && args->has("help") ? 0 : 2;
  }
  int steps = 30, long_steps = 1000;
  for (const auto& [flag, value] : {std::pair<const char*, int*>{"steps", &steps}, {"long-steps", &long_steps}}) {
    if (args->has(flag) && (!absl::SimpleAtoi(args->get(flag), value) || *value < 1)) {
      std::fprintf(stderr, "bench: --%s %s: expected a whole number of steps, at least 1\n", flag,
                   args->get(flag).c_str());
      return 2;
    }
  }
  ModelOptions options;
  if (args->has("kv-precision")) {
    auto p = kv_precision_by_name(args->get("kv-precision"));
    if (!p.ok()) {
      std::fprintf(stderr, "bench: --kv-precision: %s\n", std::string(p.status().message()).c_str());
      return 2;
    }
    options.kv_precision = *p;
  }
  enable_flush_to_zero();
  auto world = make_bench_world(args->get("scenario", kBenchScenario), args->get("model", "large"), 16, options);
  if (!world.ok()) return fail(world.status());
  const ModelConfig& c = world->model->config();
  nlohmann::ordered_json out;
  out["model"] = c.name;
  out["threads"] = 1;
  out["kv_precision"] = kv_precision_name(options.kv_precision);
  out["lights"] = world->scenario->signals.empty() ? 0 : world->scenario->signals[world->scenario->current_time_index].size();
  out["map_segments"] = world->map->size();

  const double peak = gemm_gflops();
  out["gemm_gflops"] = peak;

  // Step latency, after the cache window has filled; the work of the timed steps as counted by the decoder.
  nlohmann::ordered_json p50, p99, gflop, achieved, floor_ms;
  for (int agents : {16, 32, 64, 128}) {
    auto s = bench_session(*world, agents, 1);
    if (!s.ok()) return fail(s.status());
    for (int i = 0; i < c.window_steps; ++i)
      if (auto r = (*s)->step({}); !r.ok()) return fail(r.status());
    std::vector<double> ms;
    const double flops_before = world->model->decode_flops((*s)->decode_work());
    for (int i = 0; i < steps; ++i) {
      const auto t0 = Clock::now();
      if (auto r = (*s)->step({}); !r.ok()) return fail(r.status());
      ms.push_back(ms_since(t0));
    }
    const double step_gflop = (world->model->decode_flops((*s)->decode_work()) - flops_before) / steps / 1e9;
    double total_ms = 0;
    for (double m : ms) total_ms += m;
    const std::string key = std::to_string(agents);
    p50[key] = percentile(ms, 0.5);
    p99[key] = percentile(ms, 0.99);
    gflop[key] = step_gflop;
    achieved[key] = step_gflop * steps / (total_ms / 1e3);
    floor_ms[key] = step_gflop / peak * 1e3;
    if (!args->has("json"))
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
  if (!args->has("json"))
    std::printf("step 19, 64 agents: incremental %.1f ms, full recompute %.1f ms: %.1fx\n", inc_ms, full_ms, full_ms / inc_ms);

  // Memory of a 64-agent session over a long rollout: flat once the window is full.
  auto s = bench_session(*world, 64, 2);
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
      2 * c.decoder_layers * c.d_model * (options.kv_precision == KvPrecision::fp16 ? sizeof(uint16_t) : sizeof(float));
  out["map_bytes_shared"] = world->map->bytes();
  if (args->has("json")) {
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
