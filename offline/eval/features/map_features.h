// WOSAC map features (metrics-spec.md A5, A6): signed distance to the road edge (positive: off-road) and
// traffic-light violations.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "offline/eval/joint_scene.h"
#include "engine/map/road_edges.h"
#include "engine/scenario/scenario.h"

namespace ss {

// out[e][t]: the most off-road corner's signed distance (the 4 bottom corners of the box) of each evaluated object;
// -kExtremelyLargeDistance at invalid frames. NaN everywhere when the map has no road edge.
std::vector<std::vector<double>> distance_to_road_edge(std::span<const SceneObject> objects,
                                                       std::span<const int> evaluated, const RoadEdges& edges);

// A lane for the traffic-light feature.
struct EvalLane {
  int64_t id = 0;
  std::vector<MapPoint> points;
};
// The scenario's SURFACE_STREET lanes with at least 2 points, in map order (the official feature uses these only).
std::vector<EvalLane> surface_street_lanes(const Scenario& s);

// out[e][t]: the evaluated object's centre crossed, between frames t-1 and t, the stop point of a signal in STOP or
// ARROW_STOP on the lane it is on (the lane of its nearest lane segment). `signals` is per frame (the scenario's).
// All false when there are no lanes or no signals.
std::vector<std::vector<uint8_t>> traffic_light_violation(std::span<const SceneObject> objects,
                                                          std::span<const int> evaluated,
                                                          std::span<const EvalLane> lanes,
                                                          const std::vector<std::vector<SignalLaneState>>& signals);

}  // namespace ss
