// WOSAC map features (metrics-spec.md A5, A6): signed distance to the road edge (positive: off-road) and
// traffic-light violations.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "engine/eval/joint_scene.h"
#include "engine/scenario/scenario.h"

namespace ss {

// Road-edge polylines prepared for distance queries, with a grid over their segments so a query visits only the
// segments near it (the answer is the same as scanning them all, ties included).
class RoadEdges {
 public:
  // Every polyline with at least 2 points, in the given order. Road edges are oriented with the road on their left.
  explicit RoadEdges(std::vector<std::vector<MapPoint>> polylines);
  // The scenario's road-edge features, in map order.
  static RoadEdges from_scenario(const Scenario& s);

  bool empty() const { return segments_.empty(); }
  // Signed 2-D distance from a point to the road edge: the segment nearest in 3-D (heights stretched x3, so an
  // overpass's edge is not taken for the road below) decides; the sign is + on its right (off-road), from the
  // neighbouring segment where the point lies beyond the segment's end (convex corners count as off-road).
  double signed_distance(double x, double y, double z) const;

 private:
  struct Segment {
    MapPoint a, b;
    int prev = -1, next = -1;  // neighbour segments used for the sign beyond the ends; -1: none
  };
  double side(int seg, double x, double y) const;  // sign of the point's side of segment `seg`: +1 right, -1 left

  std::vector<Segment> segments_;
  double cell_ = 20.0, min_x_ = 0, min_y_ = 0;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<int>> cells_;  // segment indices per cell, ascending
};

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
