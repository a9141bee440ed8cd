// Road edges prepared for signed-distance queries (positive: off the road). Used by the realism metrics
// (offline/eval) and by the per-tick events a session reports (engine/sim/events.h).
#pragma once

#include <vector>

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
  size_t bytes() const;  // memory held by the segments and the grid

 private:
  struct Segment {
    MapPoint a, b;
    int prev = -1, next = -1;  // neighbour segments used for the sign beyond the ends; -1: none
  };
  double side(int seg, double x, double y) const;  // sign of the point's side of segment `seg`: +1 right, -1 left

  std::vector<Segment> segments_;
  double cell_ = 5.0, min_x_ = 0, min_y_ = 0;
  int nx_ = 0, ny_ = 0;
  std::vector<int> cell_begin_;  // cell c's segments are cell_segments_[cell_begin_[c] .. cell_begin_[c + 1])
  std::vector<int> cell_segments_;  // ascending within each cell
};

}  // namespace ss
