// One generation job: a network, its demand, one SUMO run (warm-up, then a recording at 10 Hz), and the run cut
// into WOMD scenarios, encoded. Everything a job draws comes from its own seed, so a job gives the same bytes
// whichever worker runs it and whatever ran before.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "offline/dataset/windows.h"
#include "engine/tokens/fidelity.h"
#include "tools/dataset/sumo_tools.h"

namespace ss::dataset {

struct JobSpec {
  int index = 0;
  uint64_t dataset_seed = 0;
  uint64_t seed = 0;        // the job's seed (derived from the dataset seed and the index)
  std::string network;      // grid, spider, rand, osm
  double warmup = 240;      // seconds simulated before recording: the network fills up (~180-240 s)
  double record = 90;       // seconds recorded at 10 Hz
  WindowOptions windows;
  std::string id_prefix;    // scenario ids start with it
  std::string temp_root;    // job directories are created here
  bool keep_temp = false;
};

struct JobResult {
  int index = 0;
  uint64_t seed = 0;
  int sumo_seed = 0;
  std::string network, network_description, demand_description;
  std::vector<std::string> records;  // serialized WOMD Scenario protos
  std::vector<std::string> ids;
  std::vector<std::map<std::string, int>> tracks_by_type;  // per scenario
  std::vector<TokenizationFidelity> fidelity;             // per scenario: its records decoded and tokenized
  int windows = 0, dropped_collision = 0, dropped_teleport = 0, dropped_implausible = 0;
  int sumo_collisions = 0, sumo_teleports = 0;  // events SUMO reported in the recording
  std::map<std::string, double> seconds;        // per step
  std::string kept_dir;                         // the job directory, when kept
  std::vector<std::string> failed_attempts;     // errors of earlier attempts (see run_job)
};

// The SUMO seed of a job seed (SUMO takes a 32-bit int; randomTrips also gets seed + 1 and seed + 2).
int sumo_seed_of(uint64_t job_seed);

// Runs the job. When a SUMO program fails on the job's random inputs (SUMO itself crashes on a few networks, or
// randomTrips finds no trip), the job draws new inputs from a seed derived from its own and tries again, up to
// kJobAttempts times; the result lists the failures. Deterministic: the same job fails and retries the same way.
inline constexpr int kJobAttempts = 3;
absl::StatusOr<JobResult> run_job(const JobSpec& spec, const SumoTools& tools);

}  // namespace ss::dataset
