// Polyline operations the pictures need: fewer points where they change nothing visible, and parallel copies for
// double road lines.
#pragma once

#include <vector>

#include "engine/geometry/geometry.h"

namespace ss {

// Douglas-Peucker: drops points closer than `tolerance` to the simplified line (WOMD samples lanes every 0.5 m, so a
// straight lane keeps its two ends). Keeps the first and last points.
std::vector<Vec2> simplify_polyline(const std::vector<Vec2>& points, double tolerance);

// The polyline moved sideways by `offset` (positive: to the left of the direction of travel in a y-up frame). Each
// vertex moves along the mean normal of its two segments, which is exact enough for the gentle bends of road lines.
std::vector<Vec2> parallel_polyline(const std::vector<Vec2>& points, double offset);

}  // namespace ss
