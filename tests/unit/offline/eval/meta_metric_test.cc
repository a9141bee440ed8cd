// Per-scenario scoring: likelihoods, masks, rates, ADE, buckets and the meta-metric, on hand-built features.
#include "offline/eval/meta_metric.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

// One object over 3 simulated frames; every feature constant `fill` unless set.
SceneFeatures features(double fill, std::vector<uint8_t> valid = {1, 1, 1}) {
  SceneFeatures f;
  for (auto& v : f.values) v = {std::vector<double>(3, fill)};
  f.valid = {valid};
  f.ade = {0.0};
  return f;
}

TEST(MetaMetric, HistogramLikelihoodIsJointMeanOverMaskedFrames) {
  SceneFeatures log = features(0);
  log.values[kDistanceToNearestObject] = {{1, 2, 30}};  // bins 1, 1, 7 of [-5, 40] / 10
  SceneFeatures a = features(0), b = features(0);
  a.values[kDistanceToNearestObject] = {{1, 1, 1}};
  b.values[kDistanceToNearestObject] = {{30, 30, 30}};
  const std::vector<SceneFeatures> sims = {a, b};
  const std::vector<ObjectType> types = {ObjectType::vehicle};
  const RealismScores r = score_realism(log, sims, types);
  // 6 sim values: bins 1 and 7 hold 3 each: P = 3.1 / 7 for every log value.
  EXPECT_NEAR(r.likelihood[kDistanceToNearestObject], 3.1 / 7, 1e-12);
  // Masks: a frame the log lacks is not scored.
  SceneFeatures partial = log;
  partial.valid = {{1, 1, 0}};
  partial.values[kDistanceToNearestObject] = {{1, 2, -4.9}};  // bin 0 at the masked frame: must not count
  EXPECT_NEAR(score_realism(partial, sims, types).likelihood[kDistanceToNearestObject], 3.1 / 7, 1e-12);
}

TEST(MetaMetric, IndicationsRatesAndAde) {
  SceneFeatures log = features(0);
  SceneFeatures hit = features(0), clear = features(0);
  hit.values[kCollision] = {{0, 1, 0}};
  hit.ade = {2.0};
  clear.ade = {4.0};
  const std::vector<SceneFeatures> sims = {hit, clear};
  const std::vector<ObjectType> types = {ObjectType::vehicle};
  const RealismScores r = score_realism(log, sims, types);
  // The log never collides; one of two rollouts does: P(no collision) = (1 + 0.001) / (2 + 0.002).
  EXPECT_NEAR(r.likelihood[kCollision], 1.001 / 2.002, 1e-12);
  EXPECT_DOUBLE_EQ(r.collision_rate, 0.5);
  EXPECT_DOUBLE_EQ(r.offroad_rate, 0.0);
  EXPECT_DOUBLE_EQ(r.ade, 3.0);
  EXPECT_DOUBLE_EQ(r.min_ade, 2.0);
  // A collision at a frame the log lacks does not count.
  SceneFeatures masked = log;
  masked.valid = {{1, 0, 1}};
  EXPECT_NEAR(score_realism(masked, sims, types).likelihood[kCollision], 2.001 / 2.002, 1e-12);
}

TEST(MetaMetric, VehicleOnlyFeaturesAndUndefinedValues) {
  const SceneFeatures f = features(0);
  const std::vector<SceneFeatures> sims = {f};
  const std::vector<ObjectType> walker = {ObjectType::pedestrian};
  const RealismScores r = score_realism(f, sims, walker);
  // No vehicle: time to collision has nothing to score (NaN, metrics-spec.md A9.6); the light indication scores a
  // false log against false rollouts.
  EXPECT_TRUE(std::isnan(r.likelihood[kTimeToCollision]));
  EXPECT_NEAR(r.likelihood[kTrafficLightViolation], 1.001 / 1.002, 1e-12);
  EXPECT_TRUE(std::isnan(r.meta));
  // Three frames: speeds are scored at the middle one only, accelerations nowhere.
  EXPECT_FALSE(std::isnan(r.likelihood[kLinearSpeed]));
  EXPECT_TRUE(std::isnan(r.likelihood[kLinearAcceleration]));
}

TEST(MetaMetric, IdenticalRolloutsScoreTheirBinProbability) {
  // Every rollout equals the log: each histogram feature scores (N + 0.1) / (N + B 0.1) with N = K x 3 frames.
  SceneFeatures f = features(0);
  for (auto& v : f.valid) v = {1, 1, 1};
  const std::vector<SceneFeatures> sims(4, f);
  const std::vector<ObjectType> car = {ObjectType::vehicle};
  const RealismScores r = score_realism(f, sims, car);
  EXPECT_NEAR(r.likelihood[kLinearSpeed], 12.1 / (12 + 1.0), 1e-12);
  EXPECT_NEAR(r.likelihood[kDistanceToRoadEdge], 12.1 / 13, 1e-12);
  EXPECT_NEAR(r.likelihood[kAngularSpeed], 12.1 / (12 + 1.1), 1e-12);
  EXPECT_NEAR(r.likelihood[kOffroad], 4.001 / 4.002, 1e-12);
}

TEST(MetaMetric, MetaIsWeightedSumAndBucketsAreWeightedMeans) {
  std::array<double, kNumRealismFeatures> l;
  for (int f = 0; f < kNumRealismFeatures; ++f) l[f] = 0.1 * (f + 1);
  // interactive = (0.1 DNO + 0.25 COL + 0.1 TTC) / 0.45; map = (0.05 DRE + 0.25 OFF + 0.05 TL) / 0.35
  EXPECT_NEAR(bucket_score(RealismBucket::kinematic, l), (0.1 + 0.2 + 0.3 + 0.4) / 4, 1e-12);
  EXPECT_NEAR(bucket_score(RealismBucket::interactive, l), (0.1 * 0.5 + 0.25 * 0.6 + 0.1 * 0.7) / 0.45, 1e-12);
  EXPECT_NEAR(bucket_score(RealismBucket::map, l), (0.05 * 0.8 + 0.25 * 0.9 + 0.05 * 1.0) / 0.35, 1e-12);
  // The meta-metric on features equal to the log in every rollout, checked against its definition.
  SceneFeatures f;
  for (auto& v : f.values) v = {std::vector<double>(7, 0.0)};
  f.valid = {std::vector<uint8_t>(7, 1)};
  f.ade = {0};
  const std::vector<SceneFeatures> sims(2, f);
  const std::vector<ObjectType> car = {ObjectType::vehicle};
  const RealismScores r = score_realism(f, sims, car);
  double meta = 0;
  for (int k = 0; k < kNumRealismFeatures; ++k) meta += wosac_2025_config()[k].weight * r.likelihood[k];
  EXPECT_NEAR(r.meta, meta, 1e-12);
  EXPECT_GT(r.meta, 0.9);
}

}  // namespace
}  // namespace ss
