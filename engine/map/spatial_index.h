// A uniform-grid index over segment centres: nearest segment to a pose (with the heading filter used to pick an
// agent's anchor), segments within a radius, k nearest. Built once per map, read-only afterwards (thread-safe).
#pragma once

#include <span>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/map/segments.h"

namespace ss {

class SegmentIndex {
 public:
  explicit SegmentIndex(std::span<const MapSegment> segments, double cell_size = 10.0);

  // The segment whose centre is nearest `pose`'s position among segments whose heading differs from pose.heading by
  // less than `max_heading_diff` (radians; pass pi or more for no filter). -1 when no segment passes.
  int nearest(const Pose& pose, double max_heading_diff = kPi / 2) const;
  // Indices of segments whose centres lie within `radius` of `p`, nearest first.
  std::vector<int> within_radius(Vec2 p, double radius) const;
  // The `k` segments with centres nearest `p`, nearest first (fewer when the map has fewer).
  std::vector<int> k_nearest(Vec2 p, int k) const;
  // The same segments in no particular order: for callers that order them their own way (a sort fewer).
  std::vector<int> k_nearest_unordered(Vec2 p, int k) const;

  int size() const { return static_cast<int>(centres_.size()); }
  size_t bytes() const;  // memory held: the centres, headings and the grid (one entry per cell of the map's box)

 private:
  std::vector<int> nearest(Vec2 p, int k, bool sorted) const;  // k_nearest, sorted or not

  // implementation-defined members (grid cells, centres, headings)
  std::vector<Vec2> centres_;
  std::vector<double> headings_;
  double cell_ = 10.0;
  double min_x_ = 0, min_y_ = 0;
  int nx_ = 0, ny_ = 0;
  std::vector<int> cell_start_;  // CSR layout: segments of cell c are order_[cell_start_[c] .. cell_start_[c+1])
  std::vector<int> order_;
};

}  // namespace ss
