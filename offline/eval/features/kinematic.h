// WOSAC kinematic features: linear and angular speed and acceleration by central differences over a trajectory
// (metrics-spec.md A2). Computed on the whole trajectory (history included), then sliced to the simulated frames.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "offline/eval/joint_scene.h"

namespace ss {

struct KinematicFeatures {
  // One value per frame; NaN where a neighbour is missing (speeds at both ends, accelerations at two frames each end).
  std::vector<double> linear_speed, linear_acceleration, angular_speed, angular_acceleration;
};

// Validity is not consulted (as in the official code): invalid frames are masked out when scoring.
// Speed uses the 3-D position; headings are differenced through wrap() so a turn across +-pi stays small.
KinematicFeatures kinematic_features(std::span<const BoxState> states, double dt);

// The scoring masks from the logged validity of the simulated frames: a speed needs both neighbours valid, an
// acceleration both neighbouring speeds valid. The first and last entries are always false.
std::vector<uint8_t> speed_validity(std::span<const uint8_t> valid);
std::vector<uint8_t> acceleration_validity(std::span<const uint8_t> valid);

}  // namespace ss
