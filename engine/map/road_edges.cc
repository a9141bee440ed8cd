#include "engine/map/road_edges.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "engine/geometry/geometry.h"

namespace ss {
namespace {

// Start and end of a polyline closer than this (squared, metres) make it a closed loop.
constexpr double kCyclicToleranceM2 = 1.0;
// Heights count this much more than plan distances when choosing the nearest road-edge segment.
constexpr double kZStretch = 3.0;

double sign_of(double v) { return v > 0 ? 1.0 : v < 0 ? -1.0 : 0.0; }

// Projection parameter of a point on a segment, in the plane; 0 for a zero-length segment (as the official
// divide_no_nan).
double plane_t(double qx, double qy, double dx, double dy) {
  const double dd = dx * dx + dy * dy;
  return dd > 0 ? (qx * dx + qy * dy) / dd : 0.0;
}

}  // namespace

RoadEdges::RoadEdges(std::vector<std::vector<MapPoint>> polylines) {
  std::erase_if(polylines, [](const auto& p) { return p.size() < 2; });
  size_t longest = 0;
  for (const auto& p : polylines) longest = std::max(longest, p.size());
  double max_x = -INFINITY, max_y = -INFINITY;
  min_x_ = INFINITY, min_y_ = INFINITY;
  for (const auto& p : polylines) {
    const double dx = p.front().x - p.back().x, dy = p.front().y - p.back().y, dz = p.front().z - p.back().z;
    // The official code pads polylines to the longest one and wraps around the padded array, so only loops as
    // long as the longest polyline really wrap (metrics-spec.md A9.4); others use their own end segments.
    const bool wraps = dx * dx + dy * dy + dz * dz < kCyclicToleranceM2 && p.size() == longest;
    const int first = static_cast<int>(segments_.size());
    const int count = static_cast<int>(p.size()) - 1;
    for (int j = 0; j < count; ++j) {
      Segment s{p[j], p[j + 1]};
      s.prev = j > 0 ? first + j - 1 : wraps ? first + count - 1 : -1;
      s.next = j + 1 < count ? first + j + 1 : wraps ? first : -1;
      segments_.push_back(s);
    }
    for (const MapPoint& q : p) {
      min_x_ = std::min(min_x_, q.x), min_y_ = std::min(min_y_, q.y);
      max_x = std::max(max_x, q.x), max_y = std::max(max_y, q.y);
    }
  }
  if (segments_.empty()) return;
  nx_ = static_cast<int>((max_x - min_x_) / cell_) + 1;
  ny_ = static_cast<int>((max_y - min_y_) / cell_) + 1;
  // Each segment goes in every cell its bounding box touches: counted first, then placed (compressed rows).
  auto for_cells = [&](const Segment& s, auto&& f) {
    const int x0 = static_cast<int>((std::min(s.a.x, s.b.x) - min_x_) / cell_);
    const int x1 = static_cast<int>((std::max(s.a.x, s.b.x) - min_x_) / cell_);
    const int y0 = static_cast<int>((std::min(s.a.y, s.b.y) - min_y_) / cell_);
    const int y1 = static_cast<int>((std::max(s.a.y, s.b.y) - min_y_) / cell_);
    for (int cy = y0; cy <= y1; ++cy)
      for (int cx = x0; cx <= x1; ++cx) f(static_cast<size_t>(cy) * nx_ + cx);
  };
  cell_begin_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (const Segment& s : segments_) for_cells(s, [&](size_t c) { ++cell_begin_[c + 1]; });
  for (size_t c = 1; c < cell_begin_.size(); ++c) cell_begin_[c] += cell_begin_[c - 1];
  cell_segments_.resize(cell_begin_.back());
  std::vector<int> fill(cell_begin_.begin(), cell_begin_.end() - 1);
  for (size_t k = 0; k < segments_.size(); ++k)
    for_cells(segments_[k], [&](size_t c) { cell_segments_[fill[c]++] = static_cast<int>(k); });
}

RoadEdges RoadEdges::from_scenario(const Scenario& s) {
  std::vector<std::vector<MapPoint>> polylines;
  for (const MapFeature& f : s.map_features)
    if (f.kind == MapFeatureKind::road_edge) polylines.push_back(f.points);
  return RoadEdges(std::move(polylines));
}

double RoadEdges::side(int seg, double x, double y) const {
  const Segment& s = segments_[seg];
  const double qx = x - s.a.x, qy = y - s.a.y, dx = s.b.x - s.a.x, dy = s.b.y - s.a.y;
  return sign_of(qx * dy - qy * dx);
}

double RoadEdges::signed_distance(double x, double y, double z) const {
  if (segments_.empty() || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
    return std::numeric_limits<double>::quiet_NaN();
  double best = INFINITY, best_2d = 0, best_t = 0;
  int best_seg = -1;
  auto visit = [&](int k) {
    const Segment& s = segments_[k];
    const double qx = x - s.a.x, qy = y - s.a.y, qz = z - s.a.z;
    const double dx = s.b.x - s.a.x, dy = s.b.y - s.a.y, dz = s.b.z - s.a.z;
    const double t = plane_t(qx, qy, dx, dy);
    const double c = std::clamp(t, 0.0, 1.0);
    const double ex = qx - c * dx, ey = qy - c * dy, ez = qz - c * dz;
    const double d3 = std::sqrt(ex * ex + ey * ey + kZStretch * kZStretch * ez * ez);
    // Lowest index among equals, as the official argmin over the segments in map order.
    if (d3 < best || (d3 == best && k < best_seg)) best = d3, best_seg = k, best_2d = std::sqrt(ex * ex + ey * ey), best_t = t;
  };
  // Rings of cells around the point's cell, until no farther cell can hold a nearer segment: a segment in no cell
  // of rings 0..r lies outside their square, at least r cells plus the point's margin inside its own cell away,
  // and the 3-D distance is never below the plane distance.
  // Clamped so far-off points (placeholder positions) cannot overflow the cell arithmetic; their margin is 0.
  const int cx = static_cast<int>(std::clamp(std::floor((x - min_x_) / cell_), -1e6, 1e6));
  const int cy = static_cast<int>(std::clamp(std::floor((y - min_y_) / cell_), -1e6, 1e6));
  const double fx = x - (min_x_ + cx * cell_), fy = y - (min_y_ + cy * cell_);
  const double margin = std::max(0.0, std::min({fx, cell_ - fx, fy, cell_ - fy}) - 1e-9);  // 1e-9: rounding
  const int gap_x = cx < 0 ? -cx : cx >= nx_ ? cx - nx_ + 1 : 0;
  const int gap_y = cy < 0 ? -cy : cy >= ny_ ? cy - ny_ + 1 : 0;
  const int last_ring = std::max({std::abs(cx), std::abs(cx - nx_ + 1), std::abs(cy), std::abs(cy - ny_ + 1)});
  for (int r = std::max(gap_x, gap_y); r <= last_ring; ++r) {
    for (int gy = cy - r; gy <= cy + r; ++gy) {
      if (gy < 0 || gy >= ny_) continue;
      const int step = (gy == cy - r || gy == cy + r) ? 1 : 2 * r;
      for (int gx = cx - r; gx <= cx + r; gx += std::max(step, 1)) {
        if (gx < 0 || gx >= nx_) continue;
        const size_t c = static_cast<size_t>(gy) * nx_ + gx;
        for (int j = cell_begin_[c]; j < cell_begin_[c + 1]; ++j) visit(cell_segments_[j]);
      }
    }
    if (best < r * cell_ + margin) break;
  }
  const Segment& s = segments_[best_seg];
  const double n = side(best_seg, x, y);
  double sign = n;
  if (best_t < 0 && s.prev >= 0) {
    const Segment& p = segments_[s.prev];
    const double turn = cross({p.b.x - p.a.x, p.b.y - p.a.y}, {s.b.x - s.a.x, s.b.y - s.a.y});
    const double np = side(s.prev, x, y);
    sign = turn > 0 ? std::max(n, np) : std::min(n, np);
  } else if (best_t > 1 && s.next >= 0) {
    const Segment& q = segments_[s.next];
    const double turn = cross({s.b.x - s.a.x, s.b.y - s.a.y}, {q.b.x - q.a.x, q.b.y - q.a.y});
    const double nn = side(s.next, x, y);
    sign = turn > 0 ? std::max(n, nn) : std::min(n, nn);
  }
  return sign * best_2d;
}

size_t RoadEdges::bytes() const {
  return sizeof(*this) + segments_.capacity() * sizeof(Segment) +
         (cell_begin_.capacity() + cell_segments_.capacity()) * sizeof(int);
}

}  // namespace ss
