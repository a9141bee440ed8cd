// scenestreamer-train: trains SceneStreamer in libtorch and exports the engine's weight file.
//   scenestreamer-train --config small|large --data DIR... --out DIR [--resume] [options]
//   scenestreamer-train export --checkpoint DIR/checkpoint.pt --out model.safetensors
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "tools/cli_args.h"
#include "training/plot.h"
#include "training/trainer.h"

namespace {

constexpr const char* kUsage =
    "usage: scenestreamer-train --config small|large --data PATH[,PATH...] --out DIR [--resume] [options]\n"
    "       scenestreamer-train export --checkpoint DIR/checkpoint.pt --out model.safetensors\n"
    "       scenestreamer-train plot --run DIR --out curves.svg   (loss curves per head from the run's logs)\n"
    "  --data PATHS        real WOMD scenarios to train on (TFRecord or JSON files or directories, comma-separated)\n"
    "  --synthetic PATHS   SUMO-generated scenarios (`scenestreamer dataset sumo`)\n"
    "  --val PATHS         validation scenarios (never trained on; a scenario id in both is an error)\n"
    "  --real-fraction F   share of samples drawn from --data (default 0.7)\n"
    "  --steps N --stage1-steps N --batch B --lr LR --warmup N --weight-decay W --clip C\n"
    "  --max-agents N --max-map-segments N --seed S --threads N\n"
    "  --log-every N --val-every N --val-scenarios N --checkpoint-every N\n"
    "  --eval-every N --eval-tool PATH --eval-scenarios N   a short `scenestreamer eval` of the val data\n"
    "  --stop-after N      stop after N steps in this process (checkpointed; --resume continues)\n"
    "  The run directory holds checkpoint.pt (model, optimizer, schedule, data position), latest.safetensors,\n"
    "  train_log.csv and val_log.csv. SIGINT or SIGTERM stops after the current step with a checkpoint.\n";

std::vector<std::string> paths(const std::string& s) {
  std::vector<std::string> out;
  for (auto p : absl::StrSplit(s, ',', absl::SkipEmpty())) out.emplace_back(p);
  return out;
}

int usage_error(const std::string& why) {
  std::fprintf(stderr, "scenestreamer-train: %s\n%s", why.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // OpenBLAS reads OPENBLAS_CORETYPE when it loads: without it, it does not recognise these EPYC CPUs and picks
  // slow kernels. Name the kernels the CPU can run (SkylakeX needs AVX-512) and start again, before any work.
  if (!std::getenv("OPENBLAS_CORETYPE")) {
    setenv("OPENBLAS_CORETYPE", ss::train::openblas_coretype(), 1);
    execv("/proc/self/exe", argv);
  }
  using ss::cli::parse_args;
  if (argc > 1 && std::string(argv[1]) == "export") {
    auto args = parse_args(argc, argv, 2, {"checkpoint", "out"}, {});
    if (!args.ok()) return usage_error(std::string(args.status().message()));
    if (!args->has("checkpoint") || !args->has("out")) return usage_error("export needs --checkpoint and --out");
    if (auto s = ss::train::export_checkpoint(args->get("checkpoint"), args->get("out")); !s.ok()) {
      std::fprintf(stderr, "scenestreamer-train export: %s\n", std::string(s.message()).c_str());
      return 1;
    }
    return 0;
  }
  if (argc > 1 && std::string(argv[1]) == "plot") {
    auto args = parse_args(argc, argv, 2, {"run", "out"}, {});
    if (!args.ok()) return usage_error(std::string(args.status().message()));
    if (!args->has("run") || !args->has("out")) return usage_error("plot needs --run and --out");
    if (auto s = ss::train::plot_run(args->get("run"), args->get("out")); !s.ok()) {
      std::fprintf(stderr, "scenestreamer-train plot: %s\n", std::string(s.message()).c_str());
      return 1;
    }
    return 0;
  }
  auto args = parse_args(argc, argv, 1,
                         {"config", "data", "synthetic", "val", "out", "real-fraction", "steps", "stage1-steps", "batch",
                          "lr", "warmup", "weight-decay", "clip", "max-agents", "max-map-segments", "seed", "threads",
                          "log-every", "val-every", "val-scenarios", "checkpoint-every", "eval-every", "eval-tool",
                          "eval-scenarios", "stop-after"},
                         {"resume", "help"});
  if (!args.ok()) return usage_error(std::string(args.status().message()));
  if (args->has("help")) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (!args->positional.empty()) return usage_error("unexpected argument '" + args->positional[0] + "'");
  ss::train::TrainOptions o;
  o.config = args->get("config", o.config);
  o.real_data = paths(args->get("data"));
  o.synthetic_data = paths(args->get("synthetic"));
  o.val_data = paths(args->get("val"));
  o.out = args->get("out");
  o.resume = args->has("resume");
  o.eval_tool = args->get("eval-tool");
  auto number = [&](const char* flag, auto& dst) {
    if (!args->has(flag)) return true;
    const std::string v = args->get(flag);
    bool ok = false;
    if constexpr (std::is_floating_point_v<std::decay_t<decltype(dst)>>) ok = absl::SimpleAtod(v, &dst);
    else ok = absl::SimpleAtoi(v, &dst);
    if (!ok) std::fprintf(stderr, "scenestreamer-train: --%s '%s' is not a number\n", flag, v.c_str());
    return ok;
  };
  const bool ok = number("real-fraction", o.real_fraction) && number("steps", o.steps) &&
                  number("stage1-steps", o.stage1_steps) && number("batch", o.batch) && number("lr", o.lr) &&
                  number("warmup", o.warmup) && number("weight-decay", o.weight_decay) && number("clip", o.clip) &&
                  number("max-agents", o.max_agents) && number("max-map-segments", o.max_map_segments) &&
                  number("seed", o.seed) && number("threads", o.threads) && number("log-every", o.log_every) &&
                  number("val-every", o.val_every) && number("val-scenarios", o.val_scenarios) &&
                  number("checkpoint-every", o.checkpoint_every) && number("eval-every", o.eval_every) &&
                  number("eval-scenarios", o.eval_scenarios) && number("stop-after", o.stop_after);
  if (!ok) return 2;
  if (auto s = ss::train::run_training(o); !s.ok()) {
    std::fprintf(stderr, "scenestreamer-train: %s\n", std::string(s.message()).c_str());
    return 1;
  }
  return 0;
}
