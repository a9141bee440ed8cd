// The tokenizers on real data: every real WOMD scenario in GPUDrive JSON (read in place from ../shared; the files are
// those its README lists).
#include "engine/tokens/fidelity.h"

#include <gtest/gtest.h>

#include "engine/map/focus.h"
#include "engine/scenario/read.h"

namespace ss {
namespace {

TokenizationFidelity measure_dir(const std::string& dir) {
  auto scenarios = read_scenarios(std::vector<std::string>{dir});
  EXPECT_TRUE(scenarios.ok()) << scenarios.status();
  TokenizationFidelity total;
  if (!scenarios.ok()) return total;
  for (const Scenario& s : *scenarios) {
    std::vector<MapSegment> segs = nearest_segments(segment_map(s), scenario_focus(s));
    SegmentIndex index(segs);
    total.merge(measure_tokenization(s, segs, index));
  }
  return total;
}

// Reads and tokenizes every real file (227 when this was written): 23 s of CPU; 31 s wall with one other build
// sharing the cores; both tests 113 s at a load of 9. It grows with the data (ctest's timeout: 300 s).
TEST(Fidelity, MotionTokensReproduceRealTracks) {
  TokenizationFidelity f = measure_dir(SS_DATA_DIR "/womd/json/train");
  f.merge(measure_dir(SS_DATA_DIR "/womd/json/val"));
  ASSERT_GT(f.ace.count, 10000);
  for (int t = 0; t < kNumModelTypes; ++t) {
    SCOPED_TRACE(model_type_name(t));
    ASSERT_GT(f.ace_by_type[t].count, 100);
    EXPECT_LT(f.ace_by_type[t].mean(), 0.1);
  }
  // No drift: the error at each agent's last step stays near the overall mean.
  EXPECT_LT(f.ace_last_step.mean(), 2 * f.ace.mean());
  for (size_t t = 1; t < f.ace_by_step.size(); ++t)
    if (f.ace_by_step[t].count > 100) {
      EXPECT_LT(f.ace_by_step[t].mean(), 2 * f.ace.mean()) << "step " << t;
    }
}

// The val split only (41 files): 4 s of CPU.
TEST(Fidelity, AgentStateQuantisationIsHalfABin) {
  TokenizationFidelity f = measure_dir(SS_DATA_DIR "/womd/json/val");
  ASSERT_GT(f.state_samples, 1000);
  for (int k = 0; k < kStateFields; ++k) {
    const double half_bin = (kStateRanges[k].max - kStateRanges[k].min) / (2 * (kStateBins - 1));
    EXPECT_LE(f.state_error_in_range[k].max, half_bin + 1e-9) << state_field_name(k);
  }
}

}  // namespace
}  // namespace ss
