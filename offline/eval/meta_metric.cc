#include "offline/eval/meta_metric.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "offline/eval/features/kinematic.h"

namespace ss {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool is_bernoulli(RealismFeature f) { return wosac_2025_config()[f].bernoulli; }

}  // namespace

std::vector<RealismFeature> bucket_features(RealismBucket b) {
  switch (b) {
    case RealismBucket::kinematic: return {kLinearSpeed, kLinearAcceleration, kAngularSpeed, kAngularAcceleration};
    case RealismBucket::interactive: return {kDistanceToNearestObject, kCollision, kTimeToCollision};
    case RealismBucket::map: return {kDistanceToRoadEdge, kOffroad, kTrafficLightViolation};
  }
  return {};
}

double bucket_score(RealismBucket b, const std::array<double, kNumRealismFeatures>& likelihood) {
  double sum = 0, weights = 0;
  for (RealismFeature f : bucket_features(b)) {
    sum += wosac_2025_config()[f].weight * likelihood[f];
    weights += wosac_2025_config()[f].weight;
  }
  return sum / weights;
}

std::vector<uint8_t> feature_mask(RealismFeature f, const std::vector<uint8_t>& log_valid, ObjectType type) {
  switch (f) {
    case kLinearSpeed:
    case kAngularSpeed: return speed_validity(log_valid);
    case kLinearAcceleration:
    case kAngularAcceleration: return acceleration_validity(log_valid);
    case kTimeToCollision:
    case kTrafficLightViolation: {
      // Following distance and red lights are rules for vehicles.
      if (type == ObjectType::vehicle) return log_valid;
      return std::vector<uint8_t>(log_valid.size(), 0);
    }
    default: return log_valid;
  }
}

RealismScores score_realism(const SceneFeatures& log, std::span<const SceneFeatures> sims,
                            std::span<const ObjectType> types, FrameWindow window) {
  RealismScores r;
  const size_t objects = types.size();
  const auto& config = wosac_2025_config();
  const int future = log.valid.empty() ? 0 : static_cast<int>(log.valid[0].size());
  const bool whole = window.begin <= 0 && window.end >= future;
  std::array<std::vector<std::vector<uint8_t>>, kNumRealismFeatures> masks;
  for (int f = 0; f < kNumRealismFeatures; ++f)
    for (size_t i = 0; i < objects; ++i) {
      std::vector<uint8_t> m = feature_mask(static_cast<RealismFeature>(f), log.valid[i], types[i]);
      for (int t = 0; t < static_cast<int>(m.size()); ++t)
        if (t < window.begin || t >= window.end) m[t] = 0;
      masks[f].push_back(std::move(m));
    }
  // In a part of the future, an object the log does not have in any of its frames (it left, or tracking lost it) is
  // not scored there: it would count as "never collided, never off-road" and lift the window's score. Over the whole
  // future every evaluated object counts, as in WOSAC.
  std::vector<uint8_t> scored(objects, 1);
  if (!whole)
    for (size_t i = 0; i < objects; ++i)
      scored[i] = std::any_of(masks[kCollision][i].begin(), masks[kCollision][i].end(), [](uint8_t m) { return m != 0; });
  const size_t scored_objects = static_cast<size_t>(std::count(scored.begin(), scored.end(), 1));
  r.objects = static_cast<int>(scored_objects);

  // Indications aggregate over time: did the object ever collide (go off-road, run a red light) in the masked frames.
  auto indication = [&](const SceneFeatures& s, int f, size_t i) {
    const auto& v = s.values[f][i];
    for (size_t t = 0; t < v.size(); ++t)
      if (masks[f][i][t] && v[t] > 0.5) return true;
    return false;
  };
  for (int f = 0; f < kNumRealismFeatures; ++f) {
    double sum = 0;
    size_t count = 0;
    for (size_t i = 0; i < objects; ++i) {
      if (is_bernoulli(static_cast<RealismFeature>(f))) {
        if (!scored[i]) continue;
        std::vector<uint8_t> sim;
        for (const SceneFeatures& s : sims) sim.push_back(indication(s, f, i));
        sum += bernoulli_log_likelihood(config[f].histogram.pseudo_count, indication(log, f, i), sim);
        ++count;
        continue;
      }
      // Time steps are independent samples: one histogram per object over every rollout's frames, unmasked.
      std::vector<double> sim;
      for (const SceneFeatures& s : sims) sim.insert(sim.end(), s.values[f][i].begin(), s.values[f][i].end());
      const std::vector<double> ll = histogram_log_likelihood(config[f].histogram, log.values[f][i], sim);
      for (size_t t = 0; t < ll.size(); ++t)
        if (masks[f][i][t]) sum += ll[t], ++count;
    }
    // One joint mean over every counted (object, frame), or over objects for the indications.
    r.likelihood[f] = count ? std::exp(sum / count) : kNaN;
  }
  r.meta = 0;
  for (int f = 0; f < kNumRealismFeatures; ++f) r.meta += config[f].weight * r.likelihood[f];
  r.kinematic = bucket_score(RealismBucket::kinematic, r.likelihood);
  r.interactive = bucket_score(RealismBucket::interactive, r.likelihood);
  r.map = bucket_score(RealismBucket::map, r.likelihood);

  double collisions = 0, offroads = 0, ade_sum = 0;
  r.min_ade = INFINITY;
  // A window's ADE: the mean displacement over the object's log-valid frames in it (objects without one left out).
  auto window_ade = [&](const SceneFeatures& s, size_t i) {
    if (i >= s.displacement.size()) return kNaN;
    const auto& d = s.displacement[i];
    double sum = 0;
    int n = 0;
    for (int t = std::max(window.begin, 0); t < std::min<int>(window.end, d.size()); ++t)
      if (!std::isnan(d[t])) sum += d[t], ++n;
    return n ? sum / n : kNaN;
  };
  for (const SceneFeatures& s : sims) {
    double rollout_ade = 0;
    int with_ade = 0;
    for (size_t i = 0; i < objects; ++i) {
      if (!scored[i]) continue;
      collisions += indication(s, kCollision, i);
      offroads += indication(s, kOffroad, i);
      const double a = whole ? (i < s.ade.size() ? s.ade[i] : kNaN) : window_ade(s, i);
      if (!std::isnan(a)) rollout_ade += a, ++with_ade;
    }
    rollout_ade = with_ade ? rollout_ade / with_ade : kNaN;
    ade_sum += rollout_ade;
    r.min_ade = std::min(r.min_ade, rollout_ade);
  }
  const double pairs = static_cast<double>(sims.size() * scored_objects);
  r.collision_rate = pairs ? collisions / pairs : kNaN;
  r.offroad_rate = pairs ? offroads / pairs : kNaN;
  r.ade = sims.empty() ? kNaN : ade_sum / sims.size();
  if (sims.empty() || scored_objects == 0 || std::isnan(r.ade)) r.min_ade = kNaN;
  return r;
}

}  // namespace ss
