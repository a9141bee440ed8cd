// Where the SUMO programs are: sumo, netgenerate and netconvert (Debian package sumo), randomTrips.py and the
// networks shipped with the tools (sumo-tools, under SUMO_HOME), and the Python that runs randomTrips.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace ss::dataset {

struct SumoTools {
  std::string sumo, netgenerate, netconvert;  // absolute paths
  std::string python;                         // absolute path
  std::string home;                           // SUMO_HOME
  std::string random_trips;                   // $SUMO_HOME/tools/randomTrips.py

  // "SUMO_HOME=..." for the children: randomTrips imports sumolib from there, and SUMO looks for its XML schemas.
  std::vector<std::string> env() const { return {"SUMO_HOME=" + home}; }
};

// `bin_dir` empty: the programs are looked up in `search_path` (the caller's PATH). The error says what is missing,
// where it looked, and how to fix it (install the Debian packages sumo and sumo-tools, or point at them).
absl::StatusOr<SumoTools> find_sumo_tools(const std::string& bin_dir, const std::string& search_path,
                                          const std::string& home, const std::string& python);

}  // namespace ss::dataset
