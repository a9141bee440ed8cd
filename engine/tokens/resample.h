// The model runs at 2 Hz (a step is 0.5 s): WOMD's 10 Hz frames are sampled every 5th frame (91 frames -> 19 steps,
// current frame 10 -> step 2), and 2 Hz rollouts are upsampled back to 10 Hz for WOMD files and metrics.
#pragma once

#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"

namespace ss {

inline constexpr int kFramesPerStep = 5;
inline constexpr double kStepSeconds = 0.5;
inline constexpr double kFrameSeconds = 0.1;

// One agent at one model step: what the tokenizers and the model read.
struct StepState {
  double x = 0, y = 0;   // box centre, metres
  double heading = 0;    // radians, [-pi, pi)
  double vx = 0, vy = 0; // m/s, global frame
  double length = 0, width = 0, height = 0;
  bool valid = false;

  bool operator==(const StepState&) const = default;
};

// The agent's box on the ground plane.
inline Box box_of(const StepState& s) { return {{s.x, s.y, s.heading}, s.length, s.width}; }

// Number of 2 Hz steps covering `num_frames` 10 Hz frames (frames 0, 5, 10, ...): 91 -> 19.
int num_model_steps(int num_frames);
// The step of a frame that is a multiple of 5 (frame 10 -> step 2); -1 for other frames.
int frame_to_step(int frame);

StepState step_state_from_object(const ObjectState& s);
// The track at every 5th frame.
std::vector<StepState> downsample_track(const Track& track);

// 2 Hz -> 10 Hz: (n - 1) * 5 + 1 frames. Between two valid steps, position and velocity are interpolated linearly
// and the heading through its cosine and sine (so it turns the short way); the box is taken from the earlier step.
// A frame between a valid and an invalid step is invalid, except the valid step's own frame.
std::vector<StepState> upsample_states(const std::vector<StepState>& steps);

}  // namespace ss
