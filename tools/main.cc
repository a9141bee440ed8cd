// scenestreamer: one binary, one subcommand per job.
#include <cstdio>
#include <cstring>
#include <memory>

#include "spdlog/sinks/stdout_color_sinks.h"
#include "spdlog/spdlog.h"
#include "tools/commands.h"

namespace {

constexpr const char* kUsage =
    "usage: scenestreamer <command> [arguments]\n"
    "\n"
    "commands:\n"
    "  inspect FILE... [--json]            what a scenario file holds and how faithfully the tokenizers encode it\n"
    "  convert IN... --out FILE.tfrecord   scenarios (GPUDrive JSON or WOMD TFRecord) into one WOMD TFRecord\n"
    "  simulate --scenario F --model W --out F   roll a scenario out with the model; writes a 10 Hz WOMD TFRecord\n"
    "  bench [--json]                      step latency, cached vs full recompute, session memory\n"
    "  init-weights --config C --out FILE  random model weights (safetensors; C small|large; --seed S)\n"
    "  render FILE [--step T|--animate]    a scenario or rollout as an SVG picture (map, lights, agents)\n"
    "  dataset sumo|stats ...              generate WOMD scenarios with SUMO; statistics of scenario files\n"
    "  eval --data F... --json OUT ...     realism (WOSAC 2025), motion metrics, MMD of rollouts or baselines\n"
    "\n"
    "Run `scenestreamer <command> --help` for a command's arguments.\n";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "help")) {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  // Diagnostics and progress go to stderr through spdlog, in the server's format: stdout holds a command's output
  // (tables, JSON, an SVG under `render --out -`).
  spdlog::set_default_logger(
      std::make_shared<spdlog::logger>("", std::make_shared<spdlog::sinks::stderr_color_sink_mt>()));
  const char* cmd = argv[1];
  if (!std::strcmp(cmd, "inspect")) return ss::cli::inspect_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "convert")) return ss::cli::convert_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "simulate")) return ss::cli::simulate_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "bench")) return ss::cli::bench_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "init-weights")) return ss::cli::init_weights_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "render")) return ss::cli::render_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "dataset")) return ss::cli::dataset_main(argc - 1, argv + 1);
  if (!std::strcmp(cmd, "eval")) return ss::cli::eval_main(argc - 1, argv + 1);
  std::fprintf(stderr, "scenestreamer: unknown command '%s'\n\n%s", cmd, kUsage);
  return 2;
}
