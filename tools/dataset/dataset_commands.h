// The subcommands of `scenestreamer dataset`. argv[0] is the subcommand name; each returns the exit code.
#pragma once

namespace ss::dataset {

int sumo_main(int argc, char** argv);
int stats_main(int argc, char** argv);

}  // namespace ss::dataset
