// Dataset values from per-scenario evaluations: means over scenarios, as the official aggregation does.
#pragma once

#include <array>
#include <limits>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "offline/eval/evaluate.h"

namespace ss {

struct DatasetEvaluation {
  int scenarios = 0;
  int named_scenarios = 0;  // scenarios whose evaluated objects are their SDC and tracks_to_predict
  int evaluated_objects = 0;
  RealismScores realism;    // means over scenarios; buckets from the mean likelihoods (as the official buckets)
  // Per realism window (evaluate.h), over the scenarios long enough to have it; undefined values are counted under
  // "windows.<name>.<key>".
  struct Window {
    int scenarios = 0;
    RealismScores realism;
  };
  std::vector<Window> windows;
  MotionMetrics motion_all, motion_predict;  // means of the scene values; `agents` summed
  bool has_mmd = false;
  InitialStateMmd mmd_strict, mmd_relaxed;
  double filled_share = 0;  // mean over scenarios
  int to_match = 0, matched = 0;
  double match_distance = 0;
  // Full mode: the log's and the generated agents (summed over scenarios; the generated over rollouts too), and the
  // scenarios whose generated count (mean over rollouts) is within 30 % of the log's (of those with a log agent).
  PlacedAgents placed_log, placed_generated;
  int placed_within_30 = 0, placed_scenarios = 0;
  // Over those scenarios, the Pearson correlation of the generated count (mean over rollouts) with the log's: whether
  // the model places more where the log has more (docs/model.md: the map predicts the count only so far). NaN with
  // fewer than 3 scenarios or no spread.
  double placed_count_correlation = std::numeric_limits<double>::quiet_NaN();
  std::array<FeatureHistogram, kNumRealismFeatures> histograms;  // summed
  // The ego benchmark: episode counts summed over scenarios; the background collision rate is the mean over
  // scenarios (each scenario's is the mean over its episodes).
  bool has_ego = false;
  EgoSummary ego;
  // Values undefined (NaN) in some scenarios are averaged over the others; how many were left out, by JSON key.
  std::map<std::string, int> undefined;
};

DatasetEvaluation aggregate(std::span<const ScenarioEvaluation> scenarios);

}  // namespace ss
