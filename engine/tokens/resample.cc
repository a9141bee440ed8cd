#include "engine/tokens/resample.h"

#include <cmath>

#include "engine/geometry/geometry.h"

namespace ss {

int num_model_steps(int num_frames) { return num_frames <= 0 ? 0 : (num_frames - 1) / kFramesPerStep + 1; }

int frame_to_step(int frame) { return frame >= 0 && frame % kFramesPerStep == 0 ? frame / kFramesPerStep : -1; }

StepState step_state_from_object(const ObjectState& s) {
  if (!s.valid) return {};
  return {s.x, s.y, wrap_angle(s.heading), s.vx, s.vy, s.length, s.width, s.height, true};
}

std::vector<StepState> downsample_track(const Track& track) {
  std::vector<StepState> out(num_model_steps(static_cast<int>(track.states.size())));
  for (size_t t = 0; t < out.size(); ++t) out[t] = step_state_from_object(track.states[t * kFramesPerStep]);
  return out;
}

std::vector<StepState> upsample_states(const std::vector<StepState>& steps) {
  if (steps.empty()) return {};
  std::vector<StepState> out((steps.size() - 1) * kFramesPerStep + 1);
  for (size_t t = 0; t < steps.size(); ++t) {
    const StepState& a = steps[t];
    out[t * kFramesPerStep] = a;
    if (t + 1 == steps.size() || !a.valid || !steps[t + 1].valid) continue;
    const StepState& b = steps[t + 1];
    for (int k = 1; k < kFramesPerStep; ++k) {
      double f = static_cast<double>(k) / kFramesPerStep;
      StepState& s = out[t * kFramesPerStep + k];
      s = a;
      s.x = a.x + f * (b.x - a.x);
      s.y = a.y + f * (b.y - a.y);
      s.vx = a.vx + f * (b.vx - a.vx);
      s.vy = a.vy + f * (b.vy - a.vy);
      s.heading = std::atan2((1 - f) * std::sin(a.heading) + f * std::sin(b.heading),
                             (1 - f) * std::cos(a.heading) + f * std::cos(b.heading));
    }
  }
  return out;
}

}  // namespace ss
