#include "engine/eval/features/map_features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "engine/eval/features/interactive.h"
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
  cells_.resize(static_cast<size_t>(nx_) * ny_);
  for (size_t k = 0; k < segments_.size(); ++k) {
    const Segment& s = segments_[k];
    const int x0 = static_cast<int>((std::min(s.a.x, s.b.x) - min_x_) / cell_);
    const int x1 = static_cast<int>((std::max(s.a.x, s.b.x) - min_x_) / cell_);
    const int y0 = static_cast<int>((std::min(s.a.y, s.b.y) - min_y_) / cell_);
    const int y1 = static_cast<int>((std::max(s.a.y, s.b.y) - min_y_) / cell_);
    for (int cy = y0; cy <= y1; ++cy)
      for (int cx = x0; cx <= x1; ++cx) cells_[static_cast<size_t>(cy) * nx_ + cx].push_back(static_cast<int>(k));
  }
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
  // Rings of cells around the point's cell, until no farther cell can hold a nearer segment: a cell r + 1 rings
  // out is at least r cells away, and the 3-D distance is never below the plane distance.
  // Clamped so far-off points (placeholder positions) cannot overflow the cell arithmetic.
  const int cx = static_cast<int>(std::clamp(std::floor((x - min_x_) / cell_), -1e6, 1e6));
  const int cy = static_cast<int>(std::clamp(std::floor((y - min_y_) / cell_), -1e6, 1e6));
  const int gap_x = cx < 0 ? -cx : cx >= nx_ ? cx - nx_ + 1 : 0;
  const int gap_y = cy < 0 ? -cy : cy >= ny_ ? cy - ny_ + 1 : 0;
  const int last_ring = std::max({std::abs(cx), std::abs(cx - nx_ + 1), std::abs(cy), std::abs(cy - ny_ + 1)});
  for (int r = std::max(gap_x, gap_y); r <= last_ring; ++r) {
    for (int gy = cy - r; gy <= cy + r; ++gy) {
      if (gy < 0 || gy >= ny_) continue;
      const int step = (gy == cy - r || gy == cy + r) ? 1 : 2 * r;
      for (int gx = cx - r; gx <= cx + r; gx += std::max(step, 1)) {
        if (gx < 0 || gx >= nx_) continue;
        for (int k : cells_[static_cast<size_t>(gy) * nx_ + gx]) visit(k);
      }
    }
    if (best < r * cell_) break;
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

std::vector<std::vector<double>> distance_to_road_edge(std::span<const SceneObject> objects,
                                                       std::span<const int> evaluated, const RoadEdges& edges) {
  std::vector<std::vector<double>> out;
  for (int i : evaluated) {
    const auto& states = objects[i].states;
    std::vector<double> d(states.size(), -kExtremelyLargeDistance);
    for (size_t t = 0; t < states.size(); ++t) {
      const BoxState& b = states[t];
      if (edges.empty()) {
        d[t] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      if (!b.valid) continue;
      const double c = std::cos(b.heading), s = std::sin(b.heading);
      const double sx[4] = {1, -1, -1, 1}, sy[4] = {1, 1, -1, -1};
      double worst = -INFINITY;
      for (int k = 0; k < 4; ++k) {
        const double lx = sx[k] * b.length / 2, ly = sy[k] * b.width / 2;
        worst = std::max(worst, edges.signed_distance(b.x + c * lx - s * ly, b.y + s * lx + c * ly, b.z - b.height / 2));
      }
      d[t] = worst;
    }
    out.push_back(std::move(d));
  }
  return out;
}

std::vector<EvalLane> surface_street_lanes(const Scenario& s) {
  constexpr int32_t kSurfaceStreet = 2;  // WOMD LaneCenter.LaneType TYPE_SURFACE_STREET
  std::vector<EvalLane> out;
  for (const MapFeature& f : s.map_features)
    if (f.kind == MapFeatureKind::lane && f.subtype == kSurfaceStreet && f.points.size() >= 2)
      out.push_back({f.id, f.points});
  return out;
}

namespace {

// The official code measures |q + d clip(t)| where |q - d clip(t)| is meant (metrics-spec.md A9.3). We keep the
// slip so the lane an object is "on" (and so its violations) match the official numbers.
double light_segment_distance(Vec2 p, const MapPoint& a, const MapPoint& b) {
  const double qx = p.x - a.x, qy = p.y - a.y, dx = b.x - a.x, dy = b.y - a.y;
  const double c = std::clamp(plane_t(qx, qy, dx, dy), 0.0, 1.0);
  return std::hypot(qx + c * dx, qy + c * dy);
}

// Index of the nearest segment of one lane (first among equals).
int nearest_segment(Vec2 p, const EvalLane& lane, double* dist) {
  int best = 0;
  double bd = INFINITY;
  for (size_t j = 0; j + 1 < lane.points.size(); ++j) {
    const double d = light_segment_distance(p, lane.points[j], lane.points[j + 1]);
    if (d < bd) bd = d, best = static_cast<int>(j);
  }
  if (dist) *dist = bd;
  return best;
}

bool is_stop(SignalState s) { return s == SignalState::stop || s == SignalState::arrow_stop; }

}  // namespace

std::vector<std::vector<uint8_t>> traffic_light_violation(std::span<const SceneObject> objects,
                                                          std::span<const int> evaluated,
                                                          std::span<const EvalLane> lanes,
                                                          const std::vector<std::vector<SignalLaneState>>& signals) {
  const size_t frames = objects.empty() ? 0 : objects[0].states.size();
  std::vector<std::vector<uint8_t>> out(evaluated.size(), std::vector<uint8_t>(frames, 0));
  // Signal lanes that are among the lanes considered; per frame their state and stop point (absent: unknown at
  // (0, 0), as the official tensors are filled).
  std::map<int64_t, int> lane_index;
  for (size_t k = 0; k < lanes.size(); ++k) lane_index.emplace(lanes[k].id, static_cast<int>(k));
  struct Signal {
    int lane = 0;
    std::vector<SignalState> state;
    std::vector<Vec2> stop;
  };
  std::map<int64_t, Signal> by_lane;
  for (size_t t = 0; t < signals.size() && t < frames; ++t)
    for (const SignalLaneState& ls : signals[t]) {
      auto it = lane_index.find(ls.lane);
      if (it == lane_index.end()) continue;
      Signal& sig = by_lane[ls.lane];
      sig.lane = it->second;
      sig.state.resize(frames, SignalState::unknown);
      sig.stop.resize(frames, Vec2{0, 0});
      sig.state[t] = ls.state;
      sig.stop[t] = {ls.stop_point.x, ls.stop_point.y};
    }
  if (by_lane.empty()) return out;

  // The stop line of each signal and frame: its projection on the nearest segment of its lane ("fence"), which the
  // object's projection on the same segment must pass.
  struct Fence {
    Vec2 start, dir;
    double stop_t = 0;
  };
  std::vector<std::pair<const Signal*, std::vector<Fence>>> fences;
  for (const auto& [id, sig] : by_lane) {
    std::vector<Fence> f(frames);
    const EvalLane& lane = lanes[sig.lane];
    for (size_t t = 0; t < frames; ++t) {
      const int j = nearest_segment(sig.stop[t], lane, nullptr);
      f[t].start = {lane.points[j].x, lane.points[j].y};
      f[t].dir = Vec2{lane.points[j + 1].x, lane.points[j + 1].y} - f[t].start;
      const Vec2 q = sig.stop[t] - f[t].start;
      f[t].stop_t = plane_t(q.x, q.y, f[t].dir.x, f[t].dir.y);
    }
    fences.emplace_back(&sig, std::move(f));
  }
  for (size_t e = 0; e < evaluated.size(); ++e) {
    const auto& states = objects[evaluated[e]].states;
    std::vector<int> on_lane(frames, -1);
    for (size_t t = 0; t < frames; ++t) {
      double best = INFINITY;
      const Vec2 p{states[t].x, states[t].y};
      for (size_t k = 0; k < lanes.size(); ++k) {
        double d;
        nearest_segment(p, lanes[k], &d);
        if (d < best) best = d, on_lane[t] = static_cast<int>(k);
      }
    }
    for (const auto& entry : fences) {
      const auto& sig = entry.first;
      const auto& fence = entry.second;  // (named, not a structured binding: clang cannot capture those in lambdas)
      auto along = [&](size_t t) {
        const Vec2 q = Vec2{states[t].x, states[t].y} - fence[t].start;
        return plane_t(q.x, q.y, fence[t].dir.x, fence[t].dir.y);
      };
      for (size_t t = 1; t < frames; ++t) {
        if (!states[t].valid || on_lane[t] != sig->lane || !is_stop(sig->state[t])) continue;
        if (along(t - 1) < fence[t - 1].stop_t && along(t) > fence[t].stop_t) out[e][t] = 1;
      }
    }
  }
  return out;
}

}  // namespace ss
