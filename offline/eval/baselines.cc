#include "offline/eval/baselines.h"

namespace ss {

void extend_constant_velocity(std::vector<BoxState>& states, int from, double vx, double vy) {
  const BoxState start = states[from];
  for (size_t f = from + 1; f < states.size(); ++f) {
    const double dt = (static_cast<double>(f) - from) * kEvalFrameSeconds;
    BoxState& b = states[f];
    b = start;
    b.x = start.x + vx * dt;
    b.y = start.y + vy * dt;
    b.valid = true;
  }
}

JointScene constant_velocity_scene(const Scenario& s, const std::vector<int>& tracks) {
  JointScene scene = log_scene(s, tracks);
  const int now = s.current_time_index;
  for (size_t k = 0; k < tracks.size(); ++k) {
    const ObjectState& at_now = s.tracks[tracks[k]].states[now];
    extend_constant_velocity(scene.objects[k].states, now, at_now.vx, at_now.vy);
  }
  return scene;
}

JointScene log_replay_scene(const Scenario& s, const std::vector<int>& tracks) { return log_scene(s, tracks); }

}  // namespace ss
