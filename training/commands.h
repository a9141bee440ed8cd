// The commands of `scenestreamer-train` besides training itself. argv[0] is the command's name; each returns the
// process exit code.
#pragma once

namespace ss::train {

int export_main(int argc, char** argv);  // export_command.cc
int plot_main(int argc, char** argv);    // plot_command.cc

}  // namespace ss::train
