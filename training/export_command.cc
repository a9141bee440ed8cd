// scenestreamer-train export --checkpoint DIR/checkpoint.pt --out model.safetensors
#include <cstdio>
#include <string>

#include "absl/flags/flag.h"
#include "common/command_line.h"
#include "training/commands.h"
#include "training/trainer.h"

ABSL_FLAG(std::string, checkpoint, "", "the run's checkpoint.pt (required)");
// export_: training's --out is the run directory.
ABSL_FLAG(std::string, export_out, "", "the engine weight file to write, safetensors (required)");

namespace ss::train {

int export_main(int argc, char** argv) {
  const cli::Command command{"scenestreamer-train export",
                             "usage: scenestreamer-train export --checkpoint DIR/checkpoint.pt --out model.safetensors\n"
                             "  writes the checkpoint's model as an engine weight file\n",
                             __FILE__,
                             {}};
  cli::CommandLine line;
  if (auto exit_code = cli::parse_command(command, argc, argv, &line)) return *exit_code;
  if (!line.has(FLAGS_checkpoint) || !line.has(FLAGS_export_out))
    return cli::usage_error(command, "--checkpoint and --out are required");
  if (auto s = export_checkpoint(absl::GetFlag(FLAGS_checkpoint), absl::GetFlag(FLAGS_export_out)); !s.ok()) {
    std::fprintf(stderr, "scenestreamer-train export: %s\n", std::string(s.message()).c_str());
    return 1;
  }
  return 0;
}

}  // namespace ss::train
