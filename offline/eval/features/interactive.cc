#include "offline/eval/features/interactive.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "engine/geometry/geometry.h"

namespace ss {
namespace {

constexpr double kMaxHeadingDiff = 75.0 * kPi / 180;               // beyond this the other box is crossing, not led
constexpr double kMaxHeadingDiffForSmallOverlap = 10.0 * kPi / 180;  // a barely overlapping box must be aligned
constexpr double kSmallOverlapThreshold = 0.5;                      // metres of lateral overlap

// A box's rounded-rectangle form: the core rectangle and the rounding radius.
struct RoundedBox {
  std::array<Vec2, 4> core;  // counter-clockwise
  double radius = 0;
  Vec2 centre;
  double outer = 0;  // half diagonal of the full box: no point of it lies farther from the centre
};

RoundedBox rounded_box(const BoxState& b) {
  RoundedBox r;
  r.radius = kCornerRoundingFactor * std::min(b.length, b.width) / 2;
  const double hl = b.length / 2 - r.radius, hw = b.width / 2 - r.radius;
  const double c = std::cos(b.heading), s = std::sin(b.heading);
  // Corner order of the official code: (+L, +W), (-L, +W), (-L, -W), (+L, -W): counter-clockwise.
  const double sx[4] = {1, -1, -1, 1}, sy[4] = {1, 1, -1, -1};
  for (int k = 0; k < 4; ++k) {
    const double lx = sx[k] * hl, ly = sy[k] * hw;
    r.core[k] = {b.x + c * lx - s * ly, b.y + s * lx + c * ly};
  }
  r.centre = {b.x, b.y};
  r.outer = std::sqrt(b.length * b.length + b.width * b.width) / 2;
  return r;
}

double rounded_distance(const RoundedBox& a, const RoundedBox& b) {
  return convex_polygon_signed_distance(a.core, b.core) - a.radius - b.radius;
}

// Projection interval of a polygon on an axis.
std::pair<double, double> project(std::span<const Vec2> p, Vec2 axis) {
  double lo = INFINITY, hi = -INFINITY;
  for (Vec2 v : p) {
    const double d = dot(v, axis);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  return {lo, hi};
}

std::vector<double> speeds_2d(const SceneObject& o, double dt) {
  const size_t n = o.states.size();
  std::vector<double> v(n, std::numeric_limits<double>::quiet_NaN());
  for (size_t t = 1; t + 1 < n; ++t)
    v[t] = std::hypot(o.states[t + 1].x - o.states[t - 1].x, o.states[t + 1].y - o.states[t - 1].y) / (2 * dt);
  return v;
}

}  // namespace

double convex_polygon_signed_distance(std::span<const Vec2> a, std::span<const Vec2> b) {
  // Separating-axis test over every edge normal of both polygons: the smallest overlap is the penetration depth
  // (the distance from the origin to the boundary of the Minkowski difference, which has exactly these normals).
  double min_overlap = INFINITY;
  for (std::span<const Vec2> p : {a, b}) {
    for (size_t i = 0; i < p.size(); ++i) {
      const Vec2 e = p[(i + 1) % p.size()] - p[i];
      const double len = norm(e);
      if (len == 0) continue;
      const Vec2 axis{-e.y / len, e.x / len};
      const auto [alo, ahi] = project(a, axis);
      const auto [blo, bhi] = project(b, axis);
      min_overlap = std::min(min_overlap, std::min(ahi - blo, bhi - alo));
    }
  }
  if (min_overlap >= 0 && std::isfinite(min_overlap)) return -min_overlap;
  // Disjoint: the gap between convex polygons is reached at a vertex of one and an edge of the other.
  double gap = INFINITY;
  for (int pass = 0; pass < 2; ++pass) {
    std::span<const Vec2> p = pass ? b : a, q = pass ? a : b;
    for (Vec2 v : p)
      for (size_t i = 0; i < q.size(); ++i) gap = std::min(gap, point_segment_distance(v, q[i], q[(i + 1) % q.size()]));
  }
  return gap;
}

double box_signed_distance(const BoxState& a, const BoxState& b) {
  return rounded_distance(rounded_box(a), rounded_box(b));
}

std::vector<std::vector<double>> distance_to_nearest_object(std::span<const SceneObject> objects,
                                                            std::span<const int> evaluated) {
  const size_t n = objects.size();
  const size_t frames = n ? objects[0].states.size() : 0;
  // Rounded boxes of every object and frame, built once: each is compared with every evaluated object.
  std::vector<std::vector<RoundedBox>> boxes(n);
  for (size_t j = 0; j < n; ++j)
    for (const BoxState& s : objects[j].states) boxes[j].push_back(rounded_box(s));
  std::vector<std::vector<double>> out;
  for (int i : evaluated) {
    std::vector<double> d(frames, kExtremelyLargeDistance);
    for (size_t t = 0; t < frames; ++t) {
      if (!objects[i].states[t].valid) continue;
      const RoundedBox& bi = boxes[i][t];
      double best = kExtremelyLargeDistance;
      for (size_t j = 0; j < n; ++j) {
        if (static_cast<int>(j) == i || !objects[j].states[t].valid) continue;
        const RoundedBox& bj = boxes[j][t];
        // Both boxes lie within their half diagonals of their centres: a lower bound that skips far objects.
        if (distance(bi.centre, bj.centre) - bi.outer - bj.outer >= best) continue;
        best = std::min(best, rounded_distance(bi, bj));
      }
      d[t] = best;
    }
    out.push_back(std::move(d));
  }
  return out;
}

std::vector<std::vector<double>> time_to_collision(std::span<const SceneObject> objects, std::span<const int> evaluated,
                                                   double dt) {
  const size_t n = objects.size();
  const size_t frames = n ? objects[0].states.size() : 0;
  std::vector<std::vector<double>> speed(n);
  for (size_t j = 0; j < n; ++j) speed[j] = speeds_2d(objects[j], dt);
  std::vector<std::vector<double>> out;
  for (int i : evaluated) {
    std::vector<double> ttc(frames, kMaxTimeToCollision);
    for (size_t t = 0; t < frames; ++t) {
      // The ego's own validity is not checked (as in the official code): its invalid frames are masked when scoring.
      const BoxState& ego = objects[i].states[t];
      double nearest = INFINITY;
      int ahead = -1;
      for (size_t j = 0; j < n; ++j) {
        const BoxState& o = objects[j].states[t];
        if (!o.valid) continue;
        // Not wrapped, as in the official code: headings on either side of +-pi count as opposed.
        const double yaw_diff = std::abs(o.heading - ego.heading);
        const double c = std::abs(std::cos(yaw_diff)), s = std::abs(std::sin(yaw_diff));
        // The other box's extent towards the ego, along and across the ego's heading.
        const double long_offset = o.length / 2 * c + o.width / 2 * s;
        const double lat_offset = o.length / 2 * s + o.width / 2 * c;
        const Vec2 rel = rotate(Vec2{o.x - ego.x, o.y - ego.y}, -ego.heading);
        const double along = rel.x - ego.length / 2 - long_offset;
        const double lat = std::abs(rel.y) - ego.width / 2 - lat_offset;
        const bool following = along > 0 && yaw_diff <= kMaxHeadingDiff && lat < 0 &&
                               (lat < -kSmallOverlapThreshold || yaw_diff <= kMaxHeadingDiffForSmallOverlap);
        if (following && along < nearest) nearest = along, ahead = static_cast<int>(j);
      }
      if (ahead < 0) continue;
      const double closing = speed[i][t] - speed[ahead][t];
      if (closing > 0) ttc[t] = std::min(nearest / closing, kMaxTimeToCollision);
    }
    out.push_back(std::move(ttc));
  }
  return out;
}

}  // namespace ss
