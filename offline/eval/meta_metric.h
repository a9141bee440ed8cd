// Per-scenario WOSAC scores (metrics-spec.md A7, A8): each feature's likelihood of the log under the rollouts'
// distribution, the weighted meta-metric, its three buckets, collision and offroad rates, ADE and minADE.
#pragma once

#include <array>
#include <limits>
#include <span>
#include <vector>

#include "offline/eval/estimators.h"
#include "offline/eval/scene_features.h"
#include "engine/scenario/scenario.h"

namespace ss {

struct RealismScores {
  // NaN where the feature has no valid (object, frame) in this scenario (metrics-spec.md A9.6).
  std::array<double, kNumRealismFeatures> likelihood{};
  double meta = 0;         // sum of weight x likelihood
  double kinematic = 0, interactive = 0, map = 0;  // weighted means of each bucket's likelihoods
  double collision_rate = 0, offroad_rate = 0;     // share of (rollout, object) with any collision / offroad
  double ade = 0, min_ade = 0;                     // mean over rollouts and objects; min over rollouts of the mean
  int objects = 0;  // objects scored: every evaluated one over the whole future; in a window, those the log has there
};

enum class RealismBucket { kinematic, interactive, map };
// The features of a bucket and the bucket's weighted mean of the given likelihoods.
std::vector<RealismFeature> bucket_features(RealismBucket b);
double bucket_score(RealismBucket b, const std::array<double, kNumRealismFeatures>& likelihood);

// A span of the simulated frames, [begin, end) counted from the first frame after the current one.
struct FrameWindow {
  int begin = 0, end = std::numeric_limits<int>::max();
};

// `log` is the log's features (its `valid` is the scoring mask), `sims` one per rollout (with `ade` and
// `displacement`), `types` the evaluated objects' types (time to collision and light violations score vehicles only).
// `window`: only its frames are scored. The masks are those of the whole future (a window's first frame has its
// speed when the frame before it is valid), the indications are "any in the window's frames", objects the log has
// in none of the window's frames are left out (of the indications and rates too), and ADE counts the window's
// log-valid frames (the whole future: WOSAC's ADE, history included, and every object).
RealismScores score_realism(const SceneFeatures& log, std::span<const SceneFeatures> sims,
                            std::span<const ObjectType> types, FrameWindow window = {});

// The scoring mask of a feature for one object: which of its simulated frames count (metrics-spec.md A8).
std::vector<uint8_t> feature_mask(RealismFeature f, const std::vector<uint8_t>& log_valid, ObjectType type);

}  // namespace ss
