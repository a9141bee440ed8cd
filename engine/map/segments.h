// Map segments: the units the encoder sees. Polylines are cut into pieces of at most 10 m and 30 vectors
// (crosswalks are not cut), each described by 27-d point features in the segment's own frame (paper appendix E).
#pragma once

#include <array>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"

namespace ss {

inline constexpr int kMaxVectorsPerSegment = 30;
inline constexpr double kMaxSegmentLength = 10.0;  // metres
inline constexpr int kDefaultMaxSegments = 3000;
inline constexpr int kPointFeatureDim = 27;

// The 12 map-type flags of the point features, in feature order (indices 13..24 of the 27).
enum MapTypeFlag : int {
  kFlagLane = 0, kFlagSidewalk, kFlagRoadBoundaryLine, kFlagRoadLine, kFlagBrokenLine, kFlagSolidLine,
  kFlagYellowLine, kFlagWhiteLine, kFlagDriveway, kFlagCrosswalk, kFlagSpeedBump, kFlagStopSign, kNumMapTypeFlags
};

struct MapSegment {
  Pose pose;                   // mean of vector midpoints; circular mean of vector headings
  double z = 0;                // mean height of the vector midpoints
  double length = 0;           // sum of vector lengths, metres
  int feature_index = 0;       // index into Scenario::map_features
  int64_t feature_id = 0;      // that feature's WOMD id
  MapFeatureKind kind = MapFeatureKind::lane;
  int32_t subtype = 0;         // the feature's WOMD subtype
  int first_point = 0;         // index in the feature's points of this segment's first point
  std::vector<MapPoint> points;  // global coordinates; vectors are points[i] -> points[i + 1] (1..30 vectors)
  std::array<float, kNumMapTypeFlags> flags{};  // 0/1 type flags

  int num_vectors() const { return static_cast<int>(points.size()) - 1; }
};

// Cuts every map feature into segments, in feature order. Consecutive segments of a polyline share their boundary
// point. Polygons (crosswalks, speed bumps, driveways) are closed (last point -> first point). A stop sign becomes one
// zero-length vector at its position, heading along the nearest point of the first lane it controls (0 when none).
// Features with fewer than 2 points (other than stop signs) yield no segment.
std::vector<MapSegment> segment_map(const Scenario& scenario);

// The at most `max_segments` segments whose centres are nearest `center`, nearest first (ties by original order).
std::vector<MapSegment> nearest_segments(std::vector<MapSegment> segments, Vec2 center,
                                         int max_segments = kDefaultMaxSegments);

// Point features of one segment, row-major [30][27]; rows past num_vectors() are zero (valid = 0).
// Per vector: start xyz, end xyz, direction xyz (end - start), heading, sin, cos, vector length, 12 type flags,
// segment length, valid. Positions and directions are in the segment frame (origin at pose, x along pose.heading,
// z relative to the segment's z); the heading is relative to the segment heading.
using SegmentFeatures = std::array<float, kMaxVectorsPerSegment * kPointFeatureDim>;
SegmentFeatures segment_point_features(const MapSegment& segment);

}  // namespace ss
