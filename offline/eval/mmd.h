// Initial-state realism of generated scenes (metrics-spec.md B, TrafficGen's protocol): the maximum mean discrepancy
// between the generated agents' and the log's initial states, per attribute.
#pragma once

#include <span>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"

namespace ss {

// Squared MMD of two samples (rows = points) with one Gaussian kernel exp(-|a - b|^2 / h), the bandwidth h being the
// mean squared distance between distinct points of the pooled sample; biased (diagonals included), clamped at 0.
// NaN when either sample is empty.
double gaussian_mmd2(const std::vector<std::vector<double>>& x, const std::vector<std::vector<double>>& y);

struct InitialAgent {
  double x = 0, y = 0, heading = 0;
  double length = 0, width = 0;
  double vx = 0, vy = 0;  // global frame
  ObjectType type = ObjectType::vehicle;
};

struct InitialStateMmd {
  double position = 0, heading = 0, size = 0, velocity = 0;
};

// Attributes in the frame `frame` (the SDC's pose): position (x, y), heading relative to the frame in [0, 2 pi),
// size (length, width), velocity (vx, vy) rotated into the frame.
InitialStateMmd initial_state_mmd(std::span<const InitialAgent> generated, std::span<const InitialAgent> log,
                                  const Pose& frame);

// TrafficGen's strict set: vehicles with |x| < 50 and |y| < 50 m in the frame, within 5 m of a lane centre whose
// direction is within pi/4 of their heading, the 32 nearest the frame's origin.
std::vector<InitialAgent> strict_set(std::span<const InitialAgent> agents, const Pose& frame, const Scenario& map);

}  // namespace ss
