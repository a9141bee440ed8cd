// What happened to each controlled agent between two ticks of a session: box overlaps with other agents, off road,
// a red light run, and where the agent is along its lane. RL clients build rewards and terminations from these, so
// the rules live here once instead of being guessed by every client. Pure functions of the scenario's map and two
// consecutive tick views (no session state), so a host can compute them for any tick it holds.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/map/road_edges.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/session.h"

namespace ss {

// A stop line reaches this far to each side of its stop point (half a typical 3.5-4 m lane).
inline constexpr double kStopLineHalfWidth = 2.0;
// An agent farther than this from every lane centre (heading within 90 degrees) is on no lane.
inline constexpr double kLaneMaxDistance = 4.0;

// The map as the events need it, built once per scenario (read-only afterwards: share it between threads).
struct EventMap {
  struct Lane {
    int64_t id = 0;
    std::vector<Vec2> points;    // the lane centre, in driving direction
    std::vector<double> s;       // arc length at each point (s[0] = 0)
    Vec2 lo, hi;                 // bounding box of the points
  };
  std::vector<Lane> lanes;       // lanes with at least 2 points, in map order
  RoadEdges edges{{}};           // road edges flattened to the plane (agents carry no height)
};

EventMap event_map_from_scenario(const Scenario& scenario);

// Where an agent is on its lane: the nearest lane centre whose direction is within 90 degrees of the agent's heading.
struct LanePosition {
  int64_t lane_id = -1;          // -1: no lane within kLaneMaxDistance
  double s = 0;                  // metres along the lane from its first point to the agent's projection
  double offset = 0;             // signed lateral distance of the centre, + left of the lane direction
  double heading_error = 0;      // agent heading minus lane direction, [-pi, pi)
  Vec2 direction;                // unit lane direction at the projection
};

LanePosition lane_position(const EventMap& map, const Pose& pose);

// One controlled agent's events at a tick.
struct AgentEvents {
  int64_t agent_id = 0;
  std::vector<int64_t> overlapping;  // ids of agents whose boxes overlap this agent's box, ascending
  double road_edge_distance = 0;     // the most off-road box corner's signed distance to the road edge (+: off);
                                     // NaN when the map has no road edge
  bool off_road = false;             // road_edge_distance > 0
  bool ran_red_light = false;        // the centre crossed a red light's stop line since the previous tick
  int64_t red_light_lane = -1;       // that light's lane
  LanePosition lane;
  double progress = 0;               // the centre's displacement since the previous tick along its lane's
                                     // direction (at the new position, else the old); 0 off every lane
};

// Events of every controlled agent of `after`, measured against `before` (the previous tick of the same session)
// for the crossing and the progress; an agent absent from `before` (it just entered) has neither. A light counts
// as red when it is red at `after`, the tick the crossing ends in (as WOSAC's traffic-light feature reads it).
// The stop line is the line through the light's stop point across its lane's heading, kStopLineHalfWidth to each
// side; crossing it means going from behind it to on or past it, in the lane's direction.
std::vector<AgentEvents> tick_events(const EventMap& map, const StepResult& before, const StepResult& after);

}  // namespace ss
