#include "offline/eval/mmd.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ss {

double gaussian_mmd2(const std::vector<std::vector<double>>& x, const std::vector<std::vector<double>>& y) {
  if (x.empty() || y.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::vector<const std::vector<double>*> z;
  for (const auto& v : x) z.push_back(&v);
  for (const auto& v : y) z.push_back(&v);
  const size_t n = x.size(), total = z.size();
  // Two passes over the pairs instead of a stored distance matrix: the rollouts pooled make thousands of points.
  const auto d2 = [&](size_t i, size_t j) {
    double s = 0;
    for (size_t k = 0; k < z[i]->size(); ++k) s += ((*z[i])[k] - (*z[j])[k]) * ((*z[i])[k] - (*z[j])[k]);
    return s;
  };
  double sum = 0;
  for (size_t i = 0; i < total; ++i)
    for (size_t j = i + 1; j < total; ++j) sum += 2 * d2(i, j);
  // One bandwidth from the data: the mean squared distance over distinct pairs of the pooled sample.
  const double h = sum / static_cast<double>(total * total - total);
  double xx = 0, yy = 0, xy = 0;
  for (size_t i = 0; i < total; ++i)
    for (size_t j = 0; j < total; ++j) {
      const double k = h > 0 ? std::exp(-d2(i, j) / h) : 1.0;  // h = 0: every point is the same
      if (i < n && j < n) xx += k;
      else if (i >= n && j >= n) yy += k;
      else xy += k;  // both K_XY and K_YX
    }
  const double m = static_cast<double>(total - n);
  const double mmd = xx / (n * n) + yy / (m * m) - xy / (n * m);
  return std::max(mmd, 0.0);
}

InitialStateMmd initial_state_mmd(std::span<const InitialAgent> generated, std::span<const InitialAgent> log,
                                  const Pose& frame) {
  struct Rows {
    std::vector<std::vector<double>> position, heading, size, velocity;
  };
  auto rows = [&](std::span<const InitialAgent> agents) {
    Rows r;
    for (const InitialAgent& a : agents) {
      const Vec2 p = to_local(frame, {a.x, a.y});
      const Vec2 v = rotate({a.vx, a.vy}, -frame.heading);
      double h = std::fmod(a.heading - frame.heading, 2 * kPi);
      if (h < 0) h += 2 * kPi;
      r.position.push_back({p.x, p.y});
      r.heading.push_back({h});
      r.size.push_back({a.length, a.width});
      r.velocity.push_back({v.x, v.y});
    }
    return r;
  };
  const Rows g = rows(generated), l = rows(log);
  return {gaussian_mmd2(g.position, l.position), gaussian_mmd2(g.heading, l.heading), gaussian_mmd2(g.size, l.size),
          gaussian_mmd2(g.velocity, l.velocity)};
}

std::vector<InitialAgent> strict_set(std::span<const InitialAgent> agents, const Pose& frame, const Scenario& map) {
  constexpr double kHalfBox = 50.0, kLaneDistance = 5.0, kLaneHeading = kPi / 4;
  constexpr size_t kMaxAgents = 32;
  std::vector<std::pair<double, InitialAgent>> kept;
  for (const InitialAgent& a : agents) {
    if (a.type != ObjectType::vehicle) continue;
    const Vec2 p = to_local(frame, {a.x, a.y});
    if (std::abs(p.x) >= kHalfBox || std::abs(p.y) >= kHalfBox) continue;
    bool on_lane = false;
    for (const MapFeature& f : map.map_features) {
      if (f.kind != MapFeatureKind::lane) continue;
      for (size_t j = 0; j + 1 < f.points.size() && !on_lane; ++j) {
        const Vec2 s{f.points[j].x, f.points[j].y}, e{f.points[j + 1].x, f.points[j + 1].y};
        if (s.x == e.x && s.y == e.y) continue;
        on_lane = point_segment_distance({a.x, a.y}, s, e) <= kLaneDistance &&
                  std::abs(wrap_angle(a.heading - std::atan2(e.y - s.y, e.x - s.x))) <= kLaneHeading;
      }
      if (on_lane) break;
    }
    if (on_lane) kept.push_back({norm(p), a});
  }
  std::stable_sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<InitialAgent> out;
  for (size_t i = 0; i < kept.size() && i < kMaxAgents; ++i) out.push_back(kept[i].second);
  return out;
}

}  // namespace ss
