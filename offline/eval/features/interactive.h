// WOSAC interaction features (metrics-spec.md A3, A4): signed distance to the nearest object (negative: overlap,
// i.e. a collision) and time to collision with the object followed.
#pragma once

#include <span>
#include <vector>

#include "offline/eval/joint_scene.h"
#include "engine/geometry/geometry.h"

namespace ss {

// Stands in for "no other valid object": large enough to land in the top histogram bin, finite so sums stay finite.
inline constexpr double kExtremelyLargeDistance = 1e10;
// Boxes are rounded rectangles: corners rounded by this share of half the shorter side, which fits most vehicle
// outlines better than sharp corners.
inline constexpr double kCornerRoundingFactor = 0.7;
inline constexpr double kMaxTimeToCollision = 5.0;  // seconds: the cap and the value when nothing is followed

// Signed 2-D distance between two boxes seen as rounded rectangles (z and height ignored): the gap between them,
// or minus the penetration depth when they overlap.
double box_signed_distance(const BoxState& a, const BoxState& b);

// Signed distance between two convex polygons given counter-clockwise: the Euclidean gap when disjoint; when they
// overlap, minus the smallest overlap of their projections on the edge normals (the penetration depth).
double convex_polygon_signed_distance(std::span<const Vec2> a, std::span<const Vec2> b);

// out[e][t]: the signed distance from evaluated object `evaluated[e]` (an index into `objects`) to the nearest other
// object at frame t; kExtremelyLargeDistance where either box is invalid or no other object exists.
std::vector<std::vector<double>> distance_to_nearest_object(std::span<const SceneObject> objects,
                                                            std::span<const int> evaluated);

// out[e][t]: seconds until the evaluated object reaches the nearest object it follows at constant speeds, capped at
// kMaxTimeToCollision (also when it follows nothing or is not closing in). Speeds are 2-D central differences over
// the trajectory with frame time `dt` (so the first and last frame give the cap).
std::vector<std::vector<double>> time_to_collision(std::span<const SceneObject> objects, std::span<const int> evaluated,
                                                   double dt);

}  // namespace ss
