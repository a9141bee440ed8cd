// The ten WOSAC features of one scene (the log or one rollout) for each evaluated object over the simulated frames,
// plus the displacement error against the log (metrics-spec.md A1-A6).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "offline/eval/estimators.h"
#include "offline/eval/features/map_features.h"
#include "offline/eval/joint_scene.h"

namespace ss {

// A scenario's map as the map features read it, built once and shared by the log and every rollout.
struct EvalMap {
  RoadEdges road_edges{{}};
  std::vector<EvalLane> surface_lanes;
  std::vector<std::vector<SignalLaneState>> signals;  // per frame, the log's (rollouts are scored against these too)

  static EvalMap from_scenario(const Scenario& s);
};

struct SceneFeatures {
  // values[feature][object][frame]: the frames after the current one; the indications are 0/1.
  std::array<std::vector<std::vector<double>>, kNumRealismFeatures> values;
  std::vector<std::vector<uint8_t>> valid;  // the scene's own validity over the same frames
  std::vector<double> ade;                  // per object: WOSAC ADE against the log (empty when no log was given)
  // Per object and frame after the current one: 3-D distance to the log (NaN where the log is invalid); what a
  // window's ADE averages. Empty when no log was given.
  std::vector<std::vector<double>> displacement;
};

// `evaluated` indexes `scene.objects`. Features are computed on the whole trajectory (history included, which the
// finite differences need), then the frames after `current_frame` are kept. With `log` (whose objects
// `log_evaluated` are the same objects, in the same order), `ade` holds each object's average 3-D displacement over
// the log-valid frames, history included (metrics-spec.md A8, A9.2).
SceneFeatures scene_features(const JointScene& scene, std::span<const int> evaluated, const EvalMap& map,
                             int current_frame, const JointScene* log = nullptr,
                             std::span<const int> log_evaluated = {});

}  // namespace ss
