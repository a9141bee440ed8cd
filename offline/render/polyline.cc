#include "offline/render/polyline.h"

#include <utility>

namespace ss {

std::vector<Vec2> simplify_polyline(const std::vector<Vec2>& points, double tolerance) {
  const size_t n = points.size();
  if (n <= 2) return points;
  std::vector<bool> keep(n, false);
  keep[0] = keep[n - 1] = true;
  std::vector<std::pair<size_t, size_t>> todo = {{0, n - 1}};
  while (!todo.empty()) {
    auto [a, b] = todo.back();
    todo.pop_back();
    double worst = -1;
    size_t worst_i = a;
    for (size_t i = a + 1; i < b; ++i) {
      const double d = point_segment_distance(points[i], points[a], points[b]);
      if (d > worst) worst = d, worst_i = i;
    }
    if (worst > tolerance) {
      keep[worst_i] = true;
      todo.push_back({a, worst_i});
      todo.push_back({worst_i, b});
    }
  }
  std::vector<Vec2> out;
  for (size_t i = 0; i < n; ++i)
    if (keep[i]) out.push_back(points[i]);
  return out;
}

std::vector<Vec2> parallel_polyline(const std::vector<Vec2>& points, double offset) {
  const size_t n = points.size();
  std::vector<Vec2> out;
  out.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    Vec2 dir = points[i + 1 < n ? i + 1 : i] - points[i > 0 ? i - 1 : i];
    const double len = norm(dir);
    if (len < 1e-9) {
      out.push_back(points[i]);
      continue;
    }
    dir = (1.0 / len) * dir;
    out.push_back(points[i] + offset * Vec2{-dir.y, dir.x});
  }
  return out;
}

}  // namespace ss
