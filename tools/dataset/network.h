// The road network of one job.
//   grid, spider, rand  netgenerate draws the topology (lane counts, widths, speeds and sizes drawn from the job's
//                       random numbers); its junctions then get mixed control (traffic lights, priority, priority with
//                       stop signs), and netconvert adds sidewalks, crossings, walking areas and signal programs,
//                       whose offsets are then drawn so the lights do not switch in lockstep.
//   osm                 a real OpenStreetMap network shipped with sumo-tools, cut to a box of 700-900 m around a
//                       random junction, with sidewalks and crossings guessed where the map has none.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/base/rng.h"
#include "tools/dataset/job_context.h"

namespace ss::dataset {

inline const std::vector<std::string> kNetworkKinds = {"grid", "spider", "rand", "osm"};

// The OpenStreetMap networks of sumo-tools, relative to $SUMO_HOME/tools.
inline const std::vector<std::string> kOsmNetworks = {
    "game/DRT/osm.net.xml",                                            // a town: signals, crossings, sidewalks
    "game/A10KW/osm.net.xml",                                          // motorway junction and feeder roads
    "game/bs3d/bs.net.xml",                                            // Braunschweig centre
    "sumolib/scenario/scenarios/RealWorld/acosta/acosta_buslanes.net.xml",    // Bologna: signalised arterials
    "sumolib/scenario/scenarios/RealWorld/pasubio/pasubio_buslanes.net.xml",  // Bologna
    "sumolib/scenario/scenarios/RealWorld/joined/joined_buslanes.net.xml",    // Bologna, both areas
};

struct BuiltNetwork {
  std::string file;         // net.net.xml in the job directory
  std::string description;  // e.g. "grid 4x3, 2 lanes, 50 km/h, actuated lights" for the manifest and errors
};

// `sumo_seed` seeds netgenerate and netconvert.
absl::StatusOr<BuiltNetwork> build_network(const std::string& kind, Rng& rng, int sumo_seed, JobContext& job);

}  // namespace ss::dataset
