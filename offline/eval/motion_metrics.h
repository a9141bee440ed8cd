// Motion-prediction metrics of the paper's table 2 (metrics-spec.md C): displacement errors of K rollouts against
// the log, and their diversity (how far apart the rollouts end up).
#pragma once

#include <span>

#include "offline/eval/joint_scene.h"

namespace ss {

struct MotionMetrics {
  double ade_avg = 0, ade_min = 0;  // 2-D error over an agent's valid frames: mean over rollouts / best rollout
  double fde_avg = 0, fde_min = 0;  // at the last frame valid in both log and rollout
  double add = 0;                   // mean over frames of the largest distance between two rollouts
  double fdd = 0;                   // largest distance between two rollouts' final positions
  int agents = 0;                   // agents with at least one scored frame; the values are means over them
};

// `objects` index both `log` and every rollout (the same object at the same index). Frames after `current_frame`
// are scored, where the log is valid (and, per rollout, the rollout); diversity counts frames where every rollout
// is valid. NaN values when no agent has a scored frame.
MotionMetrics motion_metrics(const JointScene& log, std::span<const JointScene> rollouts, std::span<const int> objects,
                             int current_frame);

}  // namespace ss
