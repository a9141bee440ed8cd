// Agents moved by rules instead of the model: the two baselines every closed-loop simulator offers, as session modes
// (SessionMode::log and SessionMode::idm). Both are deterministic.
//   log: every agent not controlled replays its logged state at each step (non-reactive); agents appear and vanish
//        with their logged validity.
//   idm: vehicles follow their own logged path (its geometry only) with Intelligent Driver Model speed control
//        against the nearest agent ahead on the path, the controlled ego included; pedestrians and cyclists replay
//        their log. Presence follows the log's validity as in log mode. The reference is Waymax's IDMRoutePolicy.
#pragma once

#include <optional>
#include <span>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"
#include "engine/tokens/resample.h"

namespace ss {

// IDM's parameters (Treiber, Hennecke, Helbing 2000), Waymax's defaults but for the desired speed: v0 is the log's
// speed at the next step, so a vehicle with nothing ahead keeps its logged speed profile (stops at red lights
// included, which IDM itself does not see) instead of Waymax's constant 30 m/s.
struct IdmParams {
  double min_gap = 2.0;        // s0, m
  double headway = 2.0;        // T, s
  double max_accel = 2.0;      // a, m/s^2
  double comfort_brake = 4.0;  // b, m/s^2
  double delta = 4.0;
  double max_brake = 9.0;      // the hardest braking a vehicle can do, m/s^2 (IDM's own term is unbounded)
  double stopped_speed = 0.5;  // a logged speed below this is a stop: brake at b to a standstill
  double lookahead = 50.0;     // m along the path searched for a leader
  double probe_step = 0.5;     // m between the positions of the vehicle's box tried along the path
};

// IDM's acceleration for speed v, desired speed v0, bumper-to-bumper gap to the leader and the leader's speed along
// the path (gap +inf: no leader). Clamped to [-max_brake, max_accel].
double idm_acceleration(const IdmParams& p, double v, double v0, double gap, double v_lead);

// A track's logged path: its valid 10 Hz positions with their arc length and heading.
struct LoggedPath {
  std::vector<Vec2> points;
  std::vector<double> s;        // arc length at each point, from 0
  std::vector<double> heading;  // logged heading at each point
  std::vector<int> frame;       // the point's frame
};
LoggedPath logged_path(const Track& track);
// The pose at arc length s: interpolated between points, extended along the end headings beyond either end.
Pose path_pose(const LoggedPath& path, double s);
// The arc length of the point of frame `frame` (the nearest valid frame at or before it; 0 if none).
double path_s_at_frame(const LoggedPath& path, int frame);

// One vehicle's IDM step of `dt` seconds along its path from arc length `s` at speed `v`, against `others` (their
// boxes and velocities now). Returns the new arc length and speed.
struct IdmOther {
  Box box;
  Vec2 velocity;
};
struct IdmMove {
  double s = 0, speed = 0;
  double gap = 0;  // to the leader found (+inf: none)
};
IdmMove idm_step(const IdmParams& p, const LoggedPath& path, double s, double v, double v0, double length,
                 double width, std::span<const IdmOther> others, double dt);

}  // namespace ss
