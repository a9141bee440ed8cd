// scenestreamer dataset <sumo|stats> ...
#include <cstdio>
#include <cstring>

#include "tools/commands.h"
#include "tools/dataset/dataset_commands.h"

namespace ss::cli {

namespace {
constexpr const char* kUsage =
    "usage: scenestreamer dataset <command> [arguments]\n"
    "\n"
    "commands:\n"
    "  sumo --out DIR --scenarios N --seed S   generate WOMD scenarios with SUMO (sharded TFRecords + MANIFEST)\n"
    "  stats FILE_OR_DIR... [--json]           statistics of scenario files (agents, lights, speeds)\n"
    "\n"
    "Run `scenestreamer dataset <command> --help` for a command's arguments.\n";
}  // namespace

int dataset_main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "help")) {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  if (!std::strcmp(argv[1], "sumo")) return ss::dataset::sumo_main(argc - 1, argv + 1);
  if (!std::strcmp(argv[1], "stats")) return ss::dataset::stats_main(argc - 1, argv + 1);
  std::fprintf(stderr, "scenestreamer dataset: unknown command '%s'\n\n%s", argv[1], kUsage);
  return 2;
}

}  // namespace ss::cli
