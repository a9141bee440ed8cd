// Traffic demand of one job: vehicle, bicycle and pedestrian types with varied sizes and driving styles, and
// randomTrips.py departures spread over the whole run, so agents keep entering and leaving (what the model must
// learn). Densities are departures per hour per km of lane, drawn per job within a range for the network kind:
// random networks of 1-2 lanes gridlock at the densities a grid carries.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/base/rng.h"
#include "offline/dataset/sumo_fcd.h"
#include "tools/dataset/job_context.h"

namespace ss::dataset {

struct Demand {
  std::vector<std::string> route_files;  // trips for sumo -r
  std::vector<std::string> additional;   // vType files for sumo -a
  AgentKinds kinds;                      // every vType a track can have
  AgentTypes person_types;               // person id -> vType (FCD does not say)
  std::string description;               // e.g. "cars 120/h/km, bikes 12, pedestrians 40"
};

// The vType files and the table of their kinds (also used by tests).
struct VehicleTypes {
  std::string vehicles_xml;     // vTypeDistributions "cars" and "bikes"
  std::string pedestrians_xml;  // vTypeDistribution "peds"
  AgentKinds kinds;
};
VehicleTypes make_vehicle_types(Rng& rng);

// randomTrips gives every person the distribution "peds"; this draws each person's vType from it in the trips text
// (so the converter knows the box size SUMO simulated), and records the choice in `*types`.
std::string assign_person_types(const std::string& trips_xml, const AgentKinds& kinds, Rng& rng, AgentTypes* types);

// `end` is the simulated time the departures spread over (seconds).
absl::StatusOr<Demand> build_demand(const std::string& network_kind, const std::string& net_file, Rng& rng,
                                    int sumo_seed, double end, JobContext& job);

}  // namespace ss::dataset
