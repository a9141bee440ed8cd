// Reference policies for the metrics: constant velocity (the simplest motion model) and log replay (the logged
// future itself: the oracle, an upper bound on realism that shows what "perfect" scores here).
#pragma once

#include <vector>

#include "offline/eval/joint_scene.h"

namespace ss {

// Every track in `tracks` keeps its current-frame velocity and heading after the current frame (box size and
// height held too); frames up to the current one are the log. Valid at every frame after the current one.
JointScene constant_velocity_scene(const Scenario& s, const std::vector<int>& tracks);

// The log, validity included (an object the log loses is gone from the rollout too).
JointScene log_replay_scene(const Scenario& s, const std::vector<int>& tracks);

// Moves an object on at constant velocity from frame `from` (whose state is kept) to the last frame.
void extend_constant_velocity(std::vector<BoxState>& states, int from, double vx, double vy);

}  // namespace ss
