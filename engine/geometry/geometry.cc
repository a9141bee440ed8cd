#include "engine/geometry/geometry.h"

#include <algorithm>
#include <limits>

namespace ss {

double wrap_angle(double a) {
  double w = std::fmod(a + kPi, 2 * kPi);
  if (w < 0) w += 2 * kPi;
  w -= kPi;
  return w >= kPi ? w - 2 * kPi : w;  // guards fmod rounding at the upper edge
}

double circular_mean(std::span<const double> angles) {
  double s = 0, c = 0;
  for (double a : angles) {
    s += std::sin(a);
    c += std::cos(a);
  }
  return angles.empty() ? 0.0 : std::atan2(s, c);
}

double circular_mean2(double a, double b) { return wrap_angle(a + 0.5 * wrap_angle(b - a)); }

Vec2 rotate(Vec2 v, double angle) {
  double c = std::cos(angle), s = std::sin(angle);
  return {c * v.x - s * v.y, s * v.x + c * v.y};
}

Vec2 to_local(const Pose& frame, Vec2 p) { return rotate(p - Vec2{frame.x, frame.y}, -frame.heading); }

Vec2 to_global(const Pose& frame, Vec2 local) { return rotate(local, frame.heading) + Vec2{frame.x, frame.y}; }

std::array<Vec2, 4> box_corners(const Box& b) {
  double c = std::cos(b.pose.heading), s = std::sin(b.pose.heading);
  Vec2 f{c * b.length / 2, s * b.length / 2};   // centre to front
  Vec2 l{-s * b.width / 2, c * b.width / 2};    // centre to left
  Vec2 o{b.pose.x, b.pose.y};
  return {o + f + l, o - f + l, o - f - l, o + f - l};
}

double average_corner_error(const Box& a, const Box& b) {
  auto ca = box_corners(a), cb = box_corners(b);
  double sum = 0;
  for (int i = 0; i < 4; ++i) sum += distance(ca[i], cb[i]);
  return sum / 4;
}

bool boxes_overlap(const Box& a, const Box& b) {
  // Farther apart than their half diagonals: disjoint, without the corners' trigonometry (the common case).
  const double dx = a.pose.x - b.pose.x, dy = a.pose.y - b.pose.y;
  const double reach = (norm({a.length, a.width}) + norm({b.length, b.width})) / 2;  // not hypot: a hot path, 3x slower
  if (dx * dx + dy * dy > reach * reach) return false;
  auto ca = box_corners(a), cb = box_corners(b);
  const std::array<Vec2, 4>* boxes[2] = {&ca, &cb};
  for (const auto* corners : boxes) {
    for (int e = 0; e < 2; ++e) {  // two distinct edge normals per rectangle
      Vec2 edge = (*corners)[e + 1] - (*corners)[e];
      Vec2 axis{-edge.y, edge.x};
      double amin = std::numeric_limits<double>::infinity(), amax = -amin, bmin = amin, bmax = -amin;
      for (const Vec2& p : ca) amin = std::min(amin, dot(p, axis)), amax = std::max(amax, dot(p, axis));
      for (const Vec2& p : cb) bmin = std::min(bmin, dot(p, axis)), bmax = std::max(bmax, dot(p, axis));
      if (amax <= bmin || bmax <= amin) return false;
    }
  }
  return true;
}

double point_segment_distance(Vec2 p, Vec2 a, Vec2 b) {
  Vec2 ab = b - a;
  double len2 = dot(ab, ab);
  double t = len2 > 0 ? std::clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
  return distance(p, a + t * ab);
}

double point_polyline_distance(Vec2 p, std::span<const Vec2> polyline) {
  if (polyline.empty()) return std::numeric_limits<double>::infinity();
  if (polyline.size() == 1) return distance(p, polyline[0]);
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < polyline.size(); ++i)
    best = std::min(best, point_segment_distance(p, polyline[i], polyline[i + 1]));
  return best;
}

double polyline_length(std::span<const Vec2> polyline) {
  double len = 0;
  for (size_t i = 0; i + 1 < polyline.size(); ++i) len += distance(polyline[i], polyline[i + 1]);
  return len;
}

}  // namespace ss
