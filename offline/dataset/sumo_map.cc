#include "offline/dataset/sumo_map.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

namespace ss {
namespace {

constexpr double kMetresPerSecondToMph = 2.2369362920544;
// Two carriageways whose facing borders lie closer than this share a centre line; farther apart, a median separates
// them (OpenStreetMap dual carriageways).
constexpr double kSharedCentreLineGap = 0.5;

bool is_driven(const SumoLane& l) { return l.use == SumoLaneUse::road || l.use == SumoLaneUse::bike; }

std::vector<MapPoint> to_points(const std::vector<Vec2>& pts) {
  std::vector<MapPoint> out;
  out.reserve(pts.size());
  for (const Vec2& p : pts) out.push_back({p.x, p.y, 0.0});
  return out;
}

class Builder {
 public:
  explicit Builder(const SumoNet& net) : net_(net) { map_.feature_of_lane.assign(net.lanes.size(), 0); }

  SumoMap build() {
    add_lanes();
    connect_lanes();
    add_carriageway_lines();
    add_junction_curbs();
    add_crosswalks();
    add_stop_signs();
    add_signal_links();
    for (const MapFeature& f : map_.features) {
      SumoMap::Bounds b{1e300, 1e300, -1e300, -1e300};
      for (const MapPoint& p : f.points) {
        b.min_x = std::min(b.min_x, p.x);
        b.min_y = std::min(b.min_y, p.y);
        b.max_x = std::max(b.max_x, p.x);
        b.max_y = std::max(b.max_y, p.y);
      }
      map_.bounds.push_back(b);
    }
    return std::move(map_);
  }

 private:
  MapFeature& add(MapFeatureKind kind, int32_t subtype, std::vector<MapPoint> points) {
    MapFeature f;
    f.id = static_cast<int64_t>(map_.features.size()) + 1;
    f.kind = kind;
    f.subtype = subtype;
    f.points = std::move(points);
    map_.features.push_back(std::move(f));
    return map_.features.back();
  }
  MapFeature& feature(int64_t id) { return map_.features[id - 1]; }

  void add_lanes() {
    for (size_t i = 0; i < net_.lanes.size(); ++i) {
      const SumoLane& l = net_.lanes[i];
      const SumoEdgeFunction fn = net_.edges[l.edge].function;
      if (!is_driven(l) || (fn != SumoEdgeFunction::normal && fn != SumoEdgeFunction::internal)) continue;
      const int32_t type = l.use == SumoLaneUse::bike ? 3 : (l.speed >= kFreewaySpeed ? 1 : 2);
      MapFeature& f = add(MapFeatureKind::lane, type, to_points(resample_polyline(l.shape, kMapPointSpacing)));
      f.lane.speed_limit_mph = std::round(l.speed * kMetresPerSecondToMph * 100.0) / 100.0;
      f.lane.interpolating = fn == SumoEdgeFunction::internal;
      map_.feature_of_lane[i] = f.id;
    }
  }

  void link(int from_lane, int to_lane) {
    const int64_t a = map_.feature_of_lane[from_lane], b = map_.feature_of_lane[to_lane];
    if (!a || !b) return;
    auto& exits = feature(a).lane.exit_lanes;
    if (std::find(exits.begin(), exits.end(), b) == exits.end()) exits.push_back(b);
    auto& entries = feature(b).lane.entry_lanes;
    if (std::find(entries.begin(), entries.end(), a) == entries.end()) entries.push_back(a);
  }

  // A connection drives from -> via -> to; a connection out of an internal lane continues the chain (SUMO splits
  // lanes that cross other traffic at an internal junction).
  void connect_lanes() {
    for (const SumoConnection& c : net_.connections) {
      if (c.via >= 0) {
        link(c.from_lane, c.via);
        link(c.via, c.to_lane);
      } else {
        link(c.from_lane, c.to_lane);
      }
    }
  }

  // Driven lanes of a normal edge, rightmost first.
  std::vector<int> driven_lanes(const SumoEdge& e) const {
    std::vector<int> out;
    for (int li : e.lanes)
      if (is_driven(net_.lanes[li])) out.push_back(li);
    return out;
  }

  int64_t add_line(MapFeatureKind kind, int32_t subtype, const SumoLane& lane, double side) {
    // side +1: the lane's left border, -1: its right border.
    return add(kind, subtype,
               to_points(resample_polyline(offset_polyline(lane.shape, side * lane.width / 2), kMapPointSpacing)))
        .id;
  }

  static BoundarySegment boundary(const MapFeature& lane, int64_t line, int32_t type) {
    return {0, static_cast<int32_t>(lane.points.size()) - 1, line, type};
  }

  void add_carriageway_lines() {
    std::map<std::pair<std::string, std::string>, int> by_ends;  // (from, to) -> a normal edge
    for (size_t e = 0; e < net_.edges.size(); ++e)
      if (net_.edges[e].function == SumoEdgeFunction::normal) by_ends.emplace(std::pair{net_.edges[e].from, net_.edges[e].to}, e);
    for (size_t e = 0; e < net_.edges.size(); ++e) {
      const SumoEdge& edge = net_.edges[e];
      if (edge.function != SumoEdgeFunction::normal) continue;
      const std::vector<int> lanes = driven_lanes(edge);
      if (lanes.empty()) continue;
      // Neighbours and the lines between them; SUMO lane indices grow to the left.
      for (size_t k = 0; k + 1 < lanes.size(); ++k) {
        const SumoLane& right = net_.lanes[lanes[k]];
        const SumoLane& left = net_.lanes[lanes[k + 1]];
        if (left.index != right.index + 1) continue;  // a sidewalk or rail lane between them
        const int32_t type = right.use == left.use ? static_cast<int32_t>(RoadLineType::broken_single_white)
                                                   : static_cast<int32_t>(RoadLineType::solid_single_white);
        const int64_t line = add_line(MapFeatureKind::road_line, type, right, +1);
        MapFeature& r = feature(map_.feature_of_lane[lanes[k]]);
        MapFeature& l = feature(map_.feature_of_lane[lanes[k + 1]]);
        const int32_t nr = static_cast<int32_t>(r.points.size()) - 1, nl = static_cast<int32_t>(l.points.size()) - 1;
        r.lane.left_neighbors.push_back({l.id, 0, nr, 0, nl, {{0, nr, line, type}}});
        l.lane.right_neighbors.push_back({r.id, 0, nl, 0, nr, {{0, nl, line, type}}});
        r.lane.left_boundaries.push_back(boundary(r, line, type));
        l.lane.right_boundaries.push_back(boundary(l, line, type));
      }
      const SumoLane& rightmost = net_.lanes[lanes.front()];
      const SumoLane& leftmost = net_.lanes[lanes.back()];
      add_line(MapFeatureKind::road_edge, 1, rightmost, -1);
      auto opposite = by_ends.find({edge.to, edge.from});
      if (opposite == by_ends.end() || driven_lanes(net_.edges[opposite->second]).empty()) {
        add_line(MapFeatureKind::road_edge, 1, leftmost, +1);  // a one-way road: its left side is a curb too
        continue;
      }
      const SumoEdge& other = net_.edges[opposite->second];
      const SumoLane& other_left = net_.lanes[driven_lanes(other).back()];
      const std::vector<Vec2> ours = offset_polyline(leftmost.shape, leftmost.width / 2);
      const std::vector<Vec2> theirs = offset_polyline(other_left.shape, other_left.width / 2);
      const Vec2 mid = ours[ours.size() / 2];
      if (point_polyline_distance(mid, theirs) > kSharedCentreLineGap) {
        add_line(MapFeatureKind::road_edge, 2, leftmost, +1);  // median
      } else if (edge.id < other.id) {  // one centre line per road
        const int32_t type = static_cast<int32_t>(RoadLineType::solid_double_yellow);
        const int64_t line = add_line(MapFeatureKind::road_line, type, leftmost, +1);
        MapFeature& a = feature(map_.feature_of_lane[lanes.back()]);
        a.lane.left_boundaries.push_back(boundary(a, line, type));
        centre_lines_[other.id] = line;
      }
    }
    // The second direction of each road gets the centre line as its left boundary too.
    for (const auto& [edge_id, line] : centre_lines_) {
      const std::vector<int> lanes = driven_lanes(net_.edges[net_.edge_by_id.at(edge_id)]);
      MapFeature& a = feature(map_.feature_of_lane[lanes.back()]);
      a.lane.left_boundaries.push_back(boundary(a, line, static_cast<int32_t>(RoadLineType::solid_double_yellow)));
    }
  }

  // The curb around a junction corner follows the right border of the right turn between the two rightmost lanes.
  void add_junction_curbs() {
    for (const SumoConnection& c : net_.connections) {
      if (c.via < 0 || (c.dir != 'r' && c.dir != 'R')) continue;
      const SumoLane& from = net_.lanes[c.from_lane];
      const SumoLane& to = net_.lanes[c.to_lane];
      if (net_.edges[from.edge].function != SumoEdgeFunction::normal) continue;
      const std::vector<int> fl = driven_lanes(net_.edges[from.edge]);
      const std::vector<int> tl = driven_lanes(net_.edges[to.edge]);
      if (fl.empty() || tl.empty() || fl.front() != c.from_lane || tl.front() != c.to_lane) continue;
      add_line(MapFeatureKind::road_edge, 1, net_.lanes[c.via], -1);
    }
  }

  void add_crosswalks() {
    for (const SumoLane& l : net_.lanes) {
      if (net_.edges[l.edge].function != SumoEdgeFunction::crossing) continue;
      const Vec2 a = l.shape.front(), b = l.shape.back();
      const double len = distance(a, b);
      if (len < 1e-6) continue;
      const Vec2 n = (l.width / 2 / len) * Vec2{-(b.y - a.y), b.x - a.x};  // left normal, half the width long
      add(MapFeatureKind::crosswalk, 0, to_points({a - n, b - n, b + n, a + n}));
    }
  }

  void add_stop_signs() {
    std::map<int, std::vector<int>> by_edge;  // approach edge -> its stop-controlled lanes
    for (const SumoConnection& c : net_.connections) {
      if (c.state != 's' && c.state != 'w') continue;
      const SumoLane& from = net_.lanes[c.from_lane];
      if (net_.edges[from.edge].function != SumoEdgeFunction::normal || !map_.feature_of_lane[c.from_lane]) continue;
      auto& lanes = by_edge[from.edge];
      if (std::find(lanes.begin(), lanes.end(), c.from_lane) == lanes.end()) lanes.push_back(c.from_lane);
    }
    for (auto& [edge, lanes] : by_edge) {
      std::sort(lanes.begin(), lanes.end(), [&](int a, int b) { return net_.lanes[a].index < net_.lanes[b].index; });
      const SumoLane& right = net_.lanes[lanes.front()];
      const std::vector<Vec2> curb = offset_polyline(right.shape, -right.width / 2);
      MapFeature& f = add(MapFeatureKind::stop_sign, 0, to_points({curb.back()}));
      for (int l : lanes) f.stop_sign_lanes.push_back(map_.feature_of_lane[l]);
    }
  }

  void add_signal_links() {
    for (const SumoConnection& c : net_.connections) {
      if (c.tl.empty() || c.link_index < 0 || !map_.feature_of_lane[c.from_lane]) continue;
      SignalLink s;
      s.tl = c.tl;
      s.link_index = c.link_index;
      s.dir = c.dir;
      if (c.via >= 0 && map_.feature_of_lane[c.via]) {
        s.lane = map_.feature_of_lane[c.via];
        const Vec2 p = net_.lanes[c.via].shape.front();
        s.stop_point = {p.x, p.y, 0.0};
      } else {  // no internal lanes: the approach lane, stopping at its end
        s.lane = map_.feature_of_lane[c.from_lane];
        const Vec2 p = net_.lanes[c.from_lane].shape.back();
        s.stop_point = {p.x, p.y, 0.0};
      }
      map_.signal_links.push_back(std::move(s));
    }
  }

  const SumoNet& net_;
  SumoMap map_;
  std::map<std::string, int64_t> centre_lines_;  // edge id -> centre line its opposite direction created
};


}  // namespace

std::vector<Vec2> resample_polyline(const std::vector<Vec2>& pts, double spacing) {
  if (pts.size() < 2) return pts;
  std::vector<Vec2> out{pts.front()};
  double to_next = spacing;  // distance along the polyline to the next output point
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    const Vec2 a = pts[i], b = pts[i + 1];
    const double len = distance(a, b);
    double s = to_next;
    while (s < len) {
      out.push_back(a + (s / len) * (b - a));
      s += spacing;
    }
    to_next = s - len;
  }
  // The last point always; drop a resampled point lying almost on it.
  if (out.size() > 1 && distance(out.back(), pts.back()) < 0.25 * spacing) out.pop_back();
  out.push_back(pts.back());
  return out;
}

std::vector<Vec2> offset_polyline(const std::vector<Vec2>& pts, double d) {
  const size_t n = pts.size();
  std::vector<Vec2> out(n);
  if (n < 2) return pts;
  auto unit_normal = [&](size_t i) {  // left normal of segment i -> i+1
    const Vec2 v = pts[i + 1] - pts[i];
    const double len = norm(v);
    return len > 1e-9 ? Vec2{-v.y / len, v.x / len} : Vec2{0, 0};
  };
  for (size_t i = 0; i < n; ++i) {
    Vec2 nrm;
    if (i == 0) {
      nrm = unit_normal(0);
    } else if (i == n - 1) {
      nrm = unit_normal(n - 2);
    } else {
      // Mitre joint: the bisector, lengthened so both neighbouring segments stay d away (capped at sharp corners).
      const Vec2 a = unit_normal(i - 1), b = unit_normal(i);
      Vec2 m = a + b;
      const double ml = norm(m);
      if (ml < 1e-9) {
        nrm = b;
      } else {
        m = (1.0 / ml) * m;
        const double c = std::max(dot(m, b), 0.5);  // cos of half the turn; caps the mitre at 2x
        nrm = (1.0 / c) * m;
      }
    }
    out[i] = pts[i] + d * nrm;
  }
  return out;
}

SignalState signal_state_from_sumo(char state, char dir) {
  const bool left = dir == 'l' || dir == 'L' || dir == 't';
  switch (state) {
    case 'G': return left ? SignalState::arrow_go : SignalState::go;
    case 'g': return SignalState::go;
    case 'y':
    case 'Y': return left ? SignalState::arrow_caution : SignalState::caution;
    case 'r':
    case 'R':
    case 'u': return left ? SignalState::arrow_stop : SignalState::stop;
    case 's': return SignalState::flashing_stop;
    case 'o': return SignalState::flashing_caution;
    default: return SignalState::unknown;
  }
}

SumoMap build_sumo_map(const SumoNet& net) { return Builder(net).build(); }

std::vector<MapFeature> crop_map(const SumoMap& map, Vec2 centre, double radius) {
  const double r2 = radius * radius;
  struct Range {
    int first = -1, last = -1;  // kept points [first, last]; first < 0: not kept
  };
  std::vector<Range> kept(map.features.size());
  for (size_t i = 0; i < map.features.size(); ++i) {
    const SumoMap::Bounds& b = map.bounds[i];
    const double dx = std::max({b.min_x - centre.x, 0.0, centre.x - b.max_x});
    const double dy = std::max({b.min_y - centre.y, 0.0, centre.y - b.max_y});
    if (dx * dx + dy * dy > r2) continue;
    const std::vector<MapPoint>& pts = map.features[i].points;
    const int n = static_cast<int>(pts.size());
    Range& r = kept[i];
    for (int k = 0; k < n; ++k) {
      if ((pts[k].x - centre.x) * (pts[k].x - centre.x) + (pts[k].y - centre.y) * (pts[k].y - centre.y) > r2) continue;
      if (r.first < 0) r.first = k;
      r.last = k;
    }
    if (r.first < 0) continue;
    const MapFeatureKind kind = map.features[i].kind;
    if (kind == MapFeatureKind::lane || kind == MapFeatureKind::road_line || kind == MapFeatureKind::road_edge) {
      r.first = std::max(r.first - 1, 0);  // reach the circle
      r.last = std::min(r.last + 1, n - 1);
      if (r.last == r.first) r.last = std::min(r.first + 1, n - 1);
    } else {
      r = {0, n - 1};  // polygons and signs stay whole
    }
  }
  auto in = [&](int64_t id) { return id > 0 && id <= static_cast<int64_t>(kept.size()) && kept[id - 1].first >= 0; };
  // A point index of feature `id` in its cut.
  auto moved = [&](int64_t id, int32_t index) {
    const Range& r = kept[id - 1];
    return std::clamp(index, r.first, r.last) - r.first;
  };
  std::vector<MapFeature> out;
  for (size_t i = 0; i < map.features.size(); ++i) {
    const Range& r = kept[i];
    if (r.first < 0) continue;
    MapFeature f = map.features[i];
    if (r.first > 0 || r.last + 1 < static_cast<int>(f.points.size()))
      f.points = std::vector<MapPoint>(f.points.begin() + r.first, f.points.begin() + r.last + 1);
    std::erase_if(f.lane.entry_lanes, [&](int64_t id) { return !in(id); });
    std::erase_if(f.lane.exit_lanes, [&](int64_t id) { return !in(id); });
    std::erase_if(f.stop_sign_lanes, [&](int64_t id) { return !in(id); });
    for (auto* bs : {&f.lane.left_boundaries, &f.lane.right_boundaries}) {
      std::erase_if(*bs, [&](const BoundarySegment& b) { return !in(b.boundary_feature_id); });
      for (BoundarySegment& b : *bs) {
        b.lane_start_index = moved(f.id, b.lane_start_index);
        b.lane_end_index = moved(f.id, b.lane_end_index);
      }
    }
    for (auto* ns : {&f.lane.left_neighbors, &f.lane.right_neighbors}) {
      std::erase_if(*ns, [&](const LaneNeighbor& n) { return !in(n.feature_id); });
      for (LaneNeighbor& n : *ns) {
        n.self_start_index = moved(f.id, n.self_start_index);
        n.self_end_index = moved(f.id, n.self_end_index);
        n.neighbor_start_index = moved(n.feature_id, n.neighbor_start_index);
        n.neighbor_end_index = moved(n.feature_id, n.neighbor_end_index);
        std::erase_if(n.boundaries, [&](const BoundarySegment& b) { return !in(b.boundary_feature_id); });
        for (BoundarySegment& b : n.boundaries) {
          b.lane_start_index = moved(f.id, b.lane_start_index);
          b.lane_end_index = moved(f.id, b.lane_end_index);
        }
      }
    }
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace ss
