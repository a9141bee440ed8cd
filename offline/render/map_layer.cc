// The map layer: road surface, markings and signs. Features wholly outside every view are left out.
#include <cmath>

#include "absl/strings/str_cat.h"
#include "offline/render/layers.h"
#include "offline/render/polyline.h"
#include "offline/render/render.h"
#include "offline/render/style.h"
#include "offline/render/svg_text.h"

namespace ss {
namespace {

// Below a few pixels at any sensible radius; WOMD's 0.5 m sampling of straight lanes would otherwise dominate the file.
constexpr double kSimplifyToleranceM = 0.05;

std::vector<Vec2> svg_polyline(const Scene& scene, const MapFeature& f) {
  std::vector<Vec2> pts;
  pts.reserve(f.points.size());
  for (const MapPoint& p : f.points) pts.push_back(scene.to_svg(p.x, p.y));
  return simplify_polyline(pts, kSimplifyToleranceM);
}

bool feature_in_view(const Scene& scene, const MapFeature& f) {
  if (f.points.empty()) return false;
  Vec2 lo{f.points[0].x, f.points[0].y}, hi = lo;
  for (const MapPoint& p : f.points) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y)};
  }
  return scene.box_in_any_view(lo, hi, kViewMarginM);
}

// WOMD RoadLineType -> colour class, and whether each of its one or two lines is dashed (left, right).
struct LineStyle {
  const char* colour;
  bool is_double;
  bool dashed_left, dashed_right;
};

LineStyle road_line_style(int32_t type) {
  switch (static_cast<RoadLineType>(type)) {
    case RoadLineType::broken_single_white: return {"white", false, true, true};
    case RoadLineType::solid_single_white: return {"white", false, false, false};
    case RoadLineType::solid_double_white: return {"white", true, false, false};
    case RoadLineType::broken_single_yellow: return {"yellow", false, true, true};
    case RoadLineType::broken_double_yellow: return {"yellow", true, true, true};
    case RoadLineType::solid_single_yellow: return {"yellow", false, false, false};
    case RoadLineType::solid_double_yellow: return {"yellow", true, false, false};
    // Which side may pass is not recorded in the type, so the dashed line's side is arbitrary.
    case RoadLineType::passing_double_yellow: return {"yellow", true, false, true};
    case RoadLineType::unknown: break;
  }
  return {"white", false, false, false};
}

void append_line(const std::vector<Vec2>& pts, const char* colour, bool dashed, std::string& out) {
  absl::StrAppend(&out, "<path class=\"line ", colour, dashed ? " dashed" : "", "\" d=\"", svg_path_data(pts, false),
                  "\"/>");
}

// Zebra stripes run across the crossing: a pattern of bars repeating along the polygon's longest edge.
std::string zebra_pattern(const std::string& id, const std::vector<Vec2>& polygon) {
  double best = -1, angle = 0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec2 e = polygon[(i + 1) % polygon.size()] - polygon[i];
    if (norm(e) > best) best = norm(e), angle = std::atan2(e.y, e.x) * 180 / kPi;
  }
  return absl::StrCat("<pattern id=\"", id, "\" patternUnits=\"userSpaceOnUse\" width=\"1.2\" height=\"4\" ",
                      "patternTransform=\"rotate(", svg_num(angle, 1), ")\"><rect width=\".6\" height=\"4\" fill=\"",
                      colour::kCrosswalk, "\"/></pattern>");
}

std::string octagon(Vec2 c, double r) {
  std::vector<Vec2> pts;
  for (int k = 0; k < 8; ++k) {
    const double a = kPi / 8 + k * kPi / 4;
    pts.push_back({c.x + r * std::cos(a), c.y + r * std::sin(a)});
  }
  return svg_points(pts);
}

}  // namespace

void draw_map(const Scene& scene, std::string& svg) {
  std::string lanes, bike_lanes, lines, edges, crosswalks, patterns, bumps, driveways, stop_signs;
  for (size_t i = 0; i < scene.scenario.map_features.size(); ++i) {
    const MapFeature& f = scene.scenario.map_features[i];
    if (!feature_in_view(scene, f)) continue;
    const std::vector<Vec2> pts = svg_polyline(scene, f);
    switch (f.kind) {
      case MapFeatureKind::lane:
        absl::StrAppend(f.subtype == 3 ? &bike_lanes : &lanes, svg_path_data(pts, false));
        break;
      case MapFeatureKind::road_line: {
        const LineStyle st = road_line_style(f.subtype);
        if (!st.is_double) {
          append_line(pts, st.colour, st.dashed_left, lines);
        } else {
          append_line(parallel_polyline(pts, kDoubleLineGapM), st.colour, st.dashed_left, lines);
          append_line(parallel_polyline(pts, -kDoubleLineGapM), st.colour, st.dashed_right, lines);
        }
        break;
      }
      case MapFeatureKind::road_edge:
        absl::StrAppend(&edges, svg_path_data(pts, false));
        break;
      case MapFeatureKind::crosswalk: {
        const std::string id = absl::StrCat("zebra-", i);
        patterns += zebra_pattern(id, pts);
        absl::StrAppend(&crosswalks, "<path class=\"crosswalk\" fill=\"url(#", id, ")\" d=\"",
                        svg_path_data(pts, true), "\"/>");
        break;
      }
      case MapFeatureKind::speed_bump:
        absl::StrAppend(&bumps, "<path class=\"bump\" d=\"", svg_path_data(pts, true), "\"/>");
        break;
      case MapFeatureKind::driveway:
        absl::StrAppend(&driveways, "<path class=\"driveway\" d=\"", svg_path_data(pts, true), "\"/>");
        break;
      case MapFeatureKind::stop_sign:
        if (!pts.empty())
          absl::StrAppend(&stop_signs, "<polygon class=\"stop-sign\" points=\"", octagon(pts[0], 0.9), "\"/>");
        break;
    }
  }
  if (!patterns.empty()) absl::StrAppend(&svg, "<defs>", patterns, "</defs>");
  absl::StrAppend(&svg, "<g id=\"map-features\">");
  absl::StrAppend(&svg, "<g id=\"driveways\">", driveways, "</g>");
  // The road surface first, so markings lie on it.
  if (!lanes.empty()) absl::StrAppend(&svg, "<path id=\"lanes\" class=\"lane-surface\" d=\"", lanes, "\"/>");
  if (!bike_lanes.empty())
    absl::StrAppend(&svg, "<path id=\"bike-lanes\" class=\"bike-surface\" d=\"", bike_lanes, "\"/>");
  absl::StrAppend(&svg, "<g id=\"crosswalks\">", crosswalks, "</g>");
  absl::StrAppend(&svg, "<g id=\"speed-bumps\">", bumps, "</g>");
  if (!lanes.empty() || !bike_lanes.empty())
    absl::StrAppend(&svg, "<path id=\"lane-centres\" class=\"lane-centre\" d=\"", lanes, bike_lanes, "\"/>");
  absl::StrAppend(&svg, "<g id=\"road-lines\">", lines, "</g>");
  if (!edges.empty()) absl::StrAppend(&svg, "<path id=\"road-edges\" class=\"edge\" d=\"", edges, "\"/>");
  absl::StrAppend(&svg, "<g id=\"stop-signs\">", stop_signs, "</g>");
  absl::StrAppend(&svg, "</g>");
}

}  // namespace ss
