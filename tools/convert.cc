// scenestreamer convert IN... --out FILE.tfrecord
#include <cstdio>

#include "engine/scenario/read.h"
#include "tools/cli_args.h"
#include "tools/commands.h"

namespace ss::cli {

int convert_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1, {"out"}, {"help"});
  if (!args.ok() || args->has("help") || args->positional.empty() || !args->has("out")) {
    if (!args.ok()) std::fprintf(stderr, "convert: %s\n", std::string(args.status().message()).c_str());
    std::fputs("usage: scenestreamer convert IN... --out FILE.tfrecord\n"
               "  IN: GPUDrive/Nocturne .json files, WOMD TFRecords, or directories of them\n",
               args.ok() && args->has("help") ? stdout : stderr);
    return args.ok() && args->has("help") ? 0 : 2;
  }
  auto scenarios = read_scenarios(args->positional);
  if (!scenarios.ok()) {
    std::fprintf(stderr, "convert: %s\n", std::string(scenarios.status().message()).c_str());
    return 1;
  }
  const std::string out = args->get("out");
  if (auto st = write_scenarios_tfrecord(out, *scenarios); !st.ok()) {
    std::fprintf(stderr, "convert: %s\n", std::string(st.message()).c_str());
    return 1;
  }
  std::printf("wrote %zu scenarios to %s\n", scenarios->size(), out.c_str());
  return 0;
}

}  // namespace ss::cli
