// scenestreamer init-weights --config small|large [--seed S] --out FILE
// Random weights for tests and benchmarks until a trained model exists.
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <string>

#include "absl/flags/flag.h"
#include "engine/model/weights.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/shared_flags.h"

ABSL_FLAG(std::string, config, "", "the model configuration: small or large (required)");

namespace ss::cli {

int init_weights_main(int argc, char** argv) {
  const Command command{"scenestreamer init-weights",
                        "usage: scenestreamer init-weights --config small|large [--seed S] --out FILE\n"
                        "  writes random weights (N(0, 0.02); norms ones, biases zeros) as a safetensors file;\n"
                        "  the same seed gives the same bytes\n",
                        __FILE__,
                        {flag(FLAGS_seed), flag(FLAGS_out)}};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  if (!line.has(FLAGS_config) || !line.has(FLAGS_out)) return usage_error(command, "--config and --out are required");
  auto config = model_config_by_name(absl::GetFlag(FLAGS_config));
  if (!config.ok()) return usage_error(command, config.status().message());
  const uint64_t seed = absl::GetFlag(FLAGS_seed);
  const std::string out = absl::GetFlag(FLAGS_out);
  const Weights w = init_weights(*config, seed);
  if (auto st = save_weights(out, w); !st.ok()) {
    spdlog::error("init-weights: {}", std::string(st.message()));
    return 1;
  }
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(out, ec);
  std::printf("wrote %s: config %s, seed %" PRIu64 ", %" PRId64 " parameters, %" PRIuMAX " bytes\n", out.c_str(),
              config->name.c_str(), seed, w.parameter_count(), ec ? uintmax_t{0} : static_cast<uintmax_t>(bytes));
  return 0;
}

}  // namespace ss::cli
