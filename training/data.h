// The training data: scenarios read once (WOMD TFRecords and JSON, real or SUMO-generated), and a deterministic,
// resumable order of (scenario, phase) samples: each source is shuffled per epoch from the seed, and each sample
// draws its source from the mix, so a run resumed at sample k continues exactly as an unbroken one would.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenario/scenario.h"

namespace ss::train {

inline constexpr int kPhases = 5;  // a 10 Hz log gives five 2 Hz sequences

struct Corpus {
  std::vector<Scenario> scenarios;
  std::vector<std::string> files;  // what was read
};

// Reads every scenario of each path (file or directory); INVALID_ARGUMENT naming the file on any defect.
absl::StatusOr<Corpus> load_corpus(const std::vector<std::string>& paths);

struct SampleRef {
  int source = 0;    // 0 real, 1 synthetic
  int scenario = 0;
  int phase = 0;
};

struct DataCursor {
  int64_t samples = 0;  // samples drawn so far
  int64_t real = 0;     // position in the real stream
  int64_t synthetic = 0;
};

class SampleOrder {
 public:
  SampleOrder(int real_scenarios, int synthetic_scenarios, double real_fraction, uint64_t seed);
  // The next sample; advances the cursor.
  SampleRef next(DataCursor& cursor) const;
  // A per-sample seed (random agent slots), distinct per sample and never 0.
  uint64_t sample_seed(int64_t sample) const;

 private:
  SampleRef at(int source, int64_t position) const;

  int real_, synthetic_;
  double real_fraction_;
  uint64_t seed_;
};

}  // namespace ss::train
