// Plane geometry shared by every engine module: angles, poses, oriented boxes, polylines.
// Positions are doubles (WOMD maps use coordinates of several km); angles are radians.
#pragma once

#include <array>
#include <cmath>
#include <span>
#include <vector>

namespace ss {

inline constexpr double kPi = 3.14159265358979323846;

struct Vec2 {
  double x = 0;
  double y = 0;
};

inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
inline Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
inline double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
inline double cross(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
// sqrt, not hypot: 3x faster, and map coordinates are nowhere near overflow.
inline double norm(Vec2 a) { return std::sqrt(a.x * a.x + a.y * a.y); }
inline double distance(Vec2 a, Vec2 b) { return norm(a - b); }

// Wraps an angle into [-pi, pi).
double wrap_angle(double a);
// Mean direction of a set of angles (atan2 of the summed unit vectors); 0 for an empty set.
double circular_mean(std::span<const double> angles);
// Mean direction of two angles, the short way round.
double circular_mean2(double a, double b);

// A point and a heading.
struct Pose {
  double x = 0;
  double y = 0;
  double heading = 0;  // radians
};

// Coordinates of `p` in the frame of `frame` (origin at the frame's position, x along its heading).
Vec2 to_local(const Pose& frame, Vec2 p);
// Global coordinates of a point given in the frame of `frame`.
Vec2 to_global(const Pose& frame, Vec2 local);
// Rotates a vector by an angle.
Vec2 rotate(Vec2 v, double angle);

// An oriented box on the ground plane.
struct Box {
  Pose pose;
  double length = 0;  // along the heading
  double width = 0;
};

// The four corners, counter-clockwise from front-left: front-left, rear-left, rear-right, front-right.
std::array<Vec2, 4> box_corners(const Box& b);
// Mean distance between corresponding corners of two boxes (the Average Corner Error of the paper).
double average_corner_error(const Box& a, const Box& b);
// True when two boxes overlap (separating axis theorem); touching edges count as no overlap.
bool boxes_overlap(const Box& a, const Box& b);

// Distance from a point to the segment [a, b].
double point_segment_distance(Vec2 p, Vec2 a, Vec2 b);
// Distance from a point to a polyline (a single point counts as a polyline of length 0); +inf when empty.
double point_polyline_distance(Vec2 p, std::span<const Vec2> polyline);
// Total length of a polyline.
double polyline_length(std::span<const Vec2> polyline);

}  // namespace ss
