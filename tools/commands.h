// The subcommands of the `scenestreamer` binary. Each returns the process exit code.
#pragma once

namespace ss::cli {

int inspect_main(int argc, char** argv);  // argv[0] is the subcommand name
int convert_main(int argc, char** argv);
int init_weights_main(int argc, char** argv);
int simulate_main(int argc, char** argv);
int bench_main(int argc, char** argv);
int render_main(int argc, char** argv);
int dataset_main(int argc, char** argv);
int eval_main(int argc, char** argv);

}  // namespace ss::cli
