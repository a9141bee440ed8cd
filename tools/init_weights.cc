// scenestreamer init-weights --config small|large [--seed S] --out FILE
// Random weights for tests and benchmarks until a trained model exists.
#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <string>

#include "absl/strings/numbers.h"
#include "engine/model/weights.h"
#include "tools/cli_args.h"
#include "tools/commands.h"

namespace ss::cli {

int init_weights_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1, {"config", "seed", "out"}, {"help"});
  const bool help = args.ok() && args->has("help");
  if (!args.ok() || help || !args->positional.empty() || !args->has("config") || !args->has("out")) {
    if (!args.ok()) std::fprintf(stderr, "init-weights: %s\n", std::string(args.status().message()).c_str());
    else if (!help && !args->positional.empty())
      std::fprintf(stderr, "init-weights: unexpected argument '%s'\n", args->positional[0].c_str());
    std::fputs("usage: scenestreamer init-weights --config small|large [--seed S] --out FILE\n"
               "  writes random weights (N(0, 0.02); norms ones, biases zeros) as a safetensors file;\n"
               "  the same seed gives the same bytes (default seed 0)\n",
               help ? stdout : stderr);
    return help ? 0 : 2;
  }
  auto config = model_config_by_name(args->get("config"));
  if (!config.ok()) {
    std::fprintf(stderr, "init-weights: %s\n", std::string(config.status().message()).c_str());
    return 2;
  }
  uint64_t seed = 0;
  if (const std::string s = args->get("seed", "0"); !absl::SimpleAtoi(s, &seed)) {
    std::fprintf(stderr, "init-weights: --seed '%s' is not a non-negative 64-bit integer\n", s.c_str());
    return 2;
  }
  const std::string out = args->get("out");
  const Weights w = init_weights(*config, seed);
  if (auto st = save_weights(out, w); !st.ok()) {
    std::fprintf(stderr, "init-weights: %s\n", std::string(st.message()).c_str());
    return 1;
  }
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(out, ec);
  std::printf("wrote %s: config %s, seed %" PRIu64 ", %" PRId64 " parameters, %" PRIuMAX " bytes\n", out.c_str(),
              config->name.c_str(), seed, w.parameter_count(), ec ? uintmax_t{0} : static_cast<uintmax_t>(bytes));
  return 0;
}

}  // namespace ss::cli
