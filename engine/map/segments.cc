#include "engine/map/segments.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

namespace ss {
namespace {

double vector_length(const MapPoint& a, const MapPoint& b) {
  double dx = b.x - a.x, dy = b.y - a.y, dz = b.z - a.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// A vector has a heading only when it moves on the ground plane by more than a micrometre: the direction between two
// copies of one surveyed point differing by rounding (1e-13 m) is noise, and it would swing a segment's heading.
constexpr double kMinHeadingLength = 1e-6;
bool has_heading(const MapPoint& a, const MapPoint& b) { return std::hypot(b.x - a.x, b.y - a.y) > kMinHeadingLength; }

std::array<float, kNumMapTypeFlags> type_flags(const MapFeature& f) {
  std::array<float, kNumMapTypeFlags> t{};
  switch (f.kind) {
    case MapFeatureKind::lane: t[kFlagLane] = 1; break;
    case MapFeatureKind::road_edge: t[kFlagRoadBoundaryLine] = 1; break;
    case MapFeatureKind::driveway: t[kFlagDriveway] = 1; break;
    case MapFeatureKind::crosswalk: t[kFlagCrosswalk] = 1; break;
    case MapFeatureKind::speed_bump: t[kFlagSpeedBump] = 1; break;
    case MapFeatureKind::stop_sign: t[kFlagStopSign] = 1; break;
    case MapFeatureKind::road_line: {
      t[kFlagRoadLine] = 1;
      bool broken = false, solid = false, yellow = false, white = false;
      switch (static_cast<RoadLineType>(f.subtype)) {
        case RoadLineType::broken_single_white: broken = white = true; break;
        case RoadLineType::solid_single_white:
        case RoadLineType::solid_double_white: solid = white = true; break;
        case RoadLineType::broken_single_yellow:
        case RoadLineType::broken_double_yellow: broken = yellow = true; break;
        case RoadLineType::solid_single_yellow:
        case RoadLineType::solid_double_yellow: solid = yellow = true; break;
        case RoadLineType::passing_double_yellow: broken = solid = yellow = true; break;
        default: break;  // unknown (or a value WOMD does not define): a road line of no known style
      }
      t[kFlagBrokenLine] = broken;
      t[kFlagSolidLine] = solid;
      t[kFlagYellowLine] = yellow;
      t[kFlagWhiteLine] = white;
      break;
    }
  }
  return t;
}

// Fills pose, z and length from the points.
void finish_segment(MapSegment& s) {
  const int n = s.num_vectors();
  double sx = 0, sy = 0, sz = 0, hs = 0, hc = 0, len = 0;
  int headed = 0;
  double longest = -1, longest_heading = 0;
  for (int i = 0; i < n; ++i) {
    const MapPoint& a = s.points[i];
    const MapPoint& b = s.points[i + 1];
    sx += 0.5 * (a.x + b.x);
    sy += 0.5 * (a.y + b.y);
    sz += 0.5 * (a.z + b.z);
    len += vector_length(a, b);
    if (has_heading(a, b)) {
      double h = std::atan2(b.y - a.y, b.x - a.x);
      hs += std::sin(h);
      hc += std::cos(h);
      ++headed;
      // The first of the longest edges (lengths equal within a micrometre count as equal, so rounding cannot flip it).
      const double l = std::hypot(b.x - a.x, b.y - a.y);
      if (l > longest + kMinHeadingLength) longest = l, longest_heading = h;
    }
  }
  s.pose.x = sx / n;
  s.pose.y = sy / n;
  s.z = sz / n;
  s.length = len;
  // All vectors zero-length: heading 0. Directions that (nearly) cancel, as a closed polygon's edges do, have no
  // meaningful mean (atan2 of rounding noise): such a segment points along its longest edge.
  if (headed == 0)
    s.pose.heading = 0.0;
  else if (std::hypot(hs, hc) < 1e-3 * headed)
    s.pose.heading = longest_heading;
  else
    s.pose.heading = std::atan2(hs, hc);
}

MapSegment new_segment(const MapFeature& f, int feature_index, int first_point,
                       const std::array<float, kNumMapTypeFlags>& flags) {
  MapSegment s;
  s.feature_index = feature_index;
  s.feature_id = f.id;
  s.kind = f.kind;
  s.subtype = f.subtype;
  s.first_point = first_point;
  s.flags = flags;
  return s;
}

// Heading of the vector of `lane` nearest `p` (ground plane); 0 when the lane has no vector with a heading.
double nearest_vector_heading(const MapFeature& lane, Vec2 p) {
  double best = std::numeric_limits<double>::infinity(), heading = 0;
  for (size_t i = 0; i + 1 < lane.points.size(); ++i) {
    const MapPoint& a = lane.points[i];
    const MapPoint& b = lane.points[i + 1];
    if (!has_heading(a, b)) continue;
    double d = point_segment_distance(p, {a.x, a.y}, {b.x, b.y});
    if (d < best) {
      best = d;
      heading = std::atan2(b.y - a.y, b.x - a.x);
    }
  }
  return heading;
}

}  // namespace

std::vector<MapSegment> segment_map(const Scenario& scenario) {
  std::vector<MapSegment> out;
  std::unordered_map<int64_t, int> lane_by_id;  // first lane with each id, for stop-sign headings
  for (int i = 0; i < static_cast<int>(scenario.map_features.size()); ++i) {
    const MapFeature& f = scenario.map_features[i];
    if (f.kind == MapFeatureKind::lane) lane_by_id.emplace(f.id, i);
  }

  for (int fi = 0; fi < static_cast<int>(scenario.map_features.size()); ++fi) {
    const MapFeature& f = scenario.map_features[fi];
    const auto flags = type_flags(f);

    if (f.kind == MapFeatureKind::stop_sign) {
      if (f.points.empty()) continue;
      MapSegment s = new_segment(f, fi, 0, flags);
      const MapPoint& p = f.points[0];
      s.points = {p, p};
      finish_segment(s);
      if (!f.stop_sign_lanes.empty()) {
        auto it = lane_by_id.find(f.stop_sign_lanes[0]);
        if (it != lane_by_id.end())
          s.pose.heading = nearest_vector_heading(scenario.map_features[it->second], {p.x, p.y});
      }
      out.push_back(std::move(s));
      continue;
    }
    if (f.points.size() < 2) continue;

    const bool polygon = f.kind == MapFeatureKind::crosswalk || f.kind == MapFeatureKind::speed_bump ||
                         f.kind == MapFeatureKind::driveway;
    // Crosswalks stay whole (up to the vector cap): the model sees each crossing as one unit.
    const bool cut_by_length = f.kind != MapFeatureKind::crosswalk;
    const int n = static_cast<int>(f.points.size());
    // A polygon whose source already repeats its first point is closed; closing it again would add a
    // zero-length vector.
    const bool close = polygon && !(f.points.front() == f.points.back());
    const int num_points = close ? n + 1 : n;  // index n stands for point 0 again
    auto point = [&](int i) -> const MapPoint& { return f.points[i == n ? 0 : i]; };

    MapSegment s = new_segment(f, fi, 0, flags);
    s.points.push_back(point(0));
    double len = 0;
    for (int i = 0; i + 1 < num_points; ++i) {
      s.points.push_back(point(i + 1));
      len += vector_length(point(i), point(i + 1));
      bool last = i + 2 == num_points;
      if (!last && (s.num_vectors() >= kMaxVectorsPerSegment || (cut_by_length && len >= kMaxSegmentLength))) {
        finish_segment(s);
        out.push_back(std::move(s));
        s = new_segment(f, fi, i + 1, flags);  // the next segment starts at this one's end point
        s.points.push_back(point(i + 1));
        len = 0;
      }
    }
    finish_segment(s);
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<MapSegment> nearest_segments(std::vector<MapSegment> segments, Vec2 center, int max_segments) {
  std::vector<double> d2(segments.size());
  for (size_t i = 0; i < segments.size(); ++i) {
    double dx = segments[i].pose.x - center.x, dy = segments[i].pose.y - center.y;
    d2[i] = dx * dx + dy * dy;
  }
  std::vector<int> order(segments.size());
  std::iota(order.begin(), order.end(), 0);
  // Index as the second key makes the order total, so ties keep the original order.
  auto closer = [&](int a, int b) { return d2[a] < d2[b] || (d2[a] == d2[b] && a < b); };
  size_t keep = std::min(segments.size(), static_cast<size_t>(std::max(max_segments, 0)));
  std::partial_sort(order.begin(), order.begin() + keep, order.end(), closer);
  std::vector<MapSegment> out;
  out.reserve(keep);
  for (size_t i = 0; i < keep; ++i) out.push_back(std::move(segments[order[i]]));
  return out;
}

SegmentFeatures segment_point_features(const MapSegment& segment) {
  SegmentFeatures f{};
  const Pose& frame = segment.pose;
  const int n = std::min(segment.num_vectors(), kMaxVectorsPerSegment);
  for (int i = 0; i < n; ++i) {
    const MapPoint& a = segment.points[i];
    const MapPoint& b = segment.points[i + 1];
    // Positions are made local in double: global WOMD coordinates of several km would lose centimetres in float.
    Vec2 s = to_local(frame, {a.x, a.y});
    Vec2 e = to_local(frame, {b.x, b.y});
    double sz = a.z - segment.z, ez = b.z - segment.z;
    Vec2 d = rotate({b.x - a.x, b.y - a.y}, -frame.heading);
    // A zero-length vector (a stop sign, a repeated point) has no direction of its own: it points along its segment.
    double h = has_heading(a, b) ? wrap_angle(std::atan2(b.y - a.y, b.x - a.x) - frame.heading) : 0.0;
    // An edge pointing straight back (a polygon's far side) sits on the +-pi seam, where rounding would flip the raw
    // heading feature from +pi to -pi: snap the seam to -pi.
    if (h > kPi - 1e-9) h = -kPi;
    float* row = f.data() + i * kPointFeatureDim;
    const double values[13] = {s.x, s.y, sz, e.x, e.y, ez, d.x, d.y, b.z - a.z,
                               h,   std::sin(h), std::cos(h), vector_length(a, b)};
    for (int k = 0; k < 13; ++k) row[k] = static_cast<float>(values[k]);
    for (int k = 0; k < kNumMapTypeFlags; ++k) row[13 + k] = segment.flags[k];
    row[25] = static_cast<float>(segment.length);
    row[26] = 1.0f;
  }
  return f;
}

}  // namespace ss
