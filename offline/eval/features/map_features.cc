#include "offline/eval/features/map_features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "offline/eval/features/interactive.h"
#include "engine/geometry/geometry.h"

namespace ss {
namespace {

// Projection parameter of a point on a segment, in the plane; 0 for a zero-length segment (as the official
// divide_no_nan).
double plane_t(double qx, double qy, double dx, double dy) {
  const double dd = dx * dx + dy * dy;
  return dd > 0 ? (qx * dx + qy * dy) / dd : 0.0;
}

}  // namespace

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
