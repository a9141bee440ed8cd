// A SUMO network as WOMD map features, and crops of it around a point.
//   lanes       every road and bike lane of normal edges, and the internal lanes that cross junctions (interpolating);
//               entry/exit lanes from the connections (from -> via -> to), left/right neighbours on the same edge
//   road lines  between neighbouring lanes (broken white; solid white beside a bike lane); the centre line between
//               two directions of a road (solid double yellow)
//   road edges  the outer border of each carriageway (boundary), the border towards a separated opposite carriageway
//               (median), and the curb around junction corners (the right border of right turns)
//   crosswalks  every pedestrian crossing: its centre line +- half its width
//   stop signs  one per approach whose links have state s (stop) or w (all-way stop), at the curb of the stop line
// and the signal-controlled links: each drives through one internal lane, which is the lane the WOMD signal state
// names, with the lane's first point (the stop line) as stop point.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "offline/dataset/sumo_net.h"
#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"

namespace ss {

// Spacing of map polylines: WOMD's (about 0.5 m).
inline constexpr double kMapPointSpacing = 0.5;
// Lanes at or above this speed limit are freeways (80 km/h).
inline constexpr double kFreewaySpeed = 80.0 / 3.6;

struct SignalLink {
  std::string tl;         // traffic light id
  int link_index = 0;     // index into the light's state string
  int64_t lane = 0;       // lane feature id the state applies to
  MapPoint stop_point;
  char dir = 's';         // the connection's direction (turn arrows)
};

struct SumoMap {
  std::vector<MapFeature> features;  // ids 1..n in order
  std::vector<SignalLink> signal_links;
  std::vector<int64_t> feature_of_lane;  // per SumoNet lane: its lane feature id, 0 when it has none
  // Per feature: bounding box, for cropping.
  struct Bounds {
    double min_x, min_y, max_x, max_y;
  };
  std::vector<Bounds> bounds;
};

SumoMap build_sumo_map(const SumoNet& net);

// The features with a point within `radius` of `centre`, in id order. Lanes, lines and edges are cut to the circle:
// from one point before their first point inside to one point after their last (a road leaving the circle and
// coming back stays whole in between), with neighbour and boundary indices moved along. References to features
// outside the crop (entry/exit lanes, neighbours, boundaries, stop-sign lanes) are removed.
std::vector<MapFeature> crop_map(const SumoMap& map, Vec2 centre, double radius);

// Points every `spacing` metres along a polyline, keeping its first and last point.
std::vector<Vec2> resample_polyline(const std::vector<Vec2>& pts, double spacing);
// The polyline moved `d` metres to its left (negative: to its right).
std::vector<Vec2> offset_polyline(const std::vector<Vec2>& pts, double d);

// WOMD signal state of one character of a SUMO traffic-light state string, for a link of direction `dir`:
// G (priority green) is a protected arrow for left turns and U-turns, g (green, must yield) a circular green,
// y/Y yellow, r/R and u (red-yellow: still stop) red, s (stop then go) a flashing stop, o (off, blinking) a flashing
// caution; O (off) and anything else unknown. Left turns and U-turns get arrow states for G, y and r.
SignalState signal_state_from_sumo(char state, char dir);

}  // namespace ss
