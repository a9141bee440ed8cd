// scenestreamer-train plot --run DIR --out curves.svg
#include <cstdio>
#include <string>

#include "absl/flags/flag.h"
#include "common/command_line.h"
#include "training/commands.h"
#include "training/plot.h"

ABSL_FLAG(std::string, run, "", "the run directory, with its train_log.csv and val_log.csv (required)");
// plot_: training's --out is the run directory.
ABSL_FLAG(std::string, plot_out, "", "the SVG file to write (required)");

namespace ss::train {

int plot_main(int argc, char** argv) {
  const cli::Command command{"scenestreamer-train plot",
                             "usage: scenestreamer-train plot --run DIR --out curves.svg\n"
                             "  the loss curves of a run, a panel per head: train loss against the step, val loss\n"
                             "  as dots\n",
                             __FILE__,
                             {}};
  cli::CommandLine line;
  if (auto exit_code = cli::parse_command(command, argc, argv, &line)) return *exit_code;
  if (!line.has(FLAGS_run) || !line.has(FLAGS_plot_out)) return cli::usage_error(command, "--run and --out are required");
  if (auto s = plot_run(absl::GetFlag(FLAGS_run), absl::GetFlag(FLAGS_plot_out)); !s.ok()) {
    std::fprintf(stderr, "scenestreamer-train plot: %s\n", std::string(s.message()).c_str());
    return 1;
  }
  return 0;
}

}  // namespace ss::train
