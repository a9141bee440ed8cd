// What happened to each controlled agent between two ticks of a session: box overlaps with other agents, off road,
// a red light run, and where the agent is along its lane. The session computes them at every tick (Session::tick)
// and hands them to hosts in the tick's StepResult (the plain AgentEvents of session_types.h). Pure functions of
// the scenario's map and two consecutive tick views, so tests can drive them without a session.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/map/road_edges.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/session_types.h"

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
  size_t bytes() const;          // memory held (a client-sent scenario's map is its session's alone)
};

EventMap event_map_from_scenario(const Scenario& scenario);

// The lane position of an agent at `pose` (LanePosition, session_types.h).
LanePosition lane_position(const EventMap& map, const Pose& pose);

// Events of every controlled agent of `after`, measured against `before` (the previous tick of the same session)
// for the crossing and the progress; an agent absent from `before` (it just entered) has neither. A light counts
// as red when it is red at `after`, the tick the crossing ends in (as WOSAC's traffic-light feature reads it).
// The stop line is the line through the light's stop point across its lane's heading, kStopLineHalfWidth to each
// side; crossing it means going from behind it to on or past it, in the lane's direction.
std::vector<AgentEvents> tick_events(const EventMap& map, const StepResult& before, const StepResult& after);

}  // namespace ss
