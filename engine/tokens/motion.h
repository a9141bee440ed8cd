// Motion tokens: a 33 x 33 grid of (acceleration, yaw rate) controls plus START, applied through a bicycle update
// every 0.5 s step. Ground truth is found by exhaustive search of the 1089 candidates for the least Average Corner
// Error, rolling forward on the reconstructed state so that errors do not compound (paper appendix C).
#pragma once

#include <span>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/tokens/resample.h"

namespace ss {

inline constexpr int kMotionBins = 33;
inline constexpr int kMotionVocab = kMotionBins * kMotionBins;  // 1089 controls
inline constexpr int kMotionStart = kMotionVocab;                // START: the agent's first step
inline constexpr int kMotionTokens = kMotionVocab + 1;           // 1090 with START
inline constexpr double kMaxAccel = 10.0;                        // m/s^2, grid spans [-10, 10]
inline constexpr double kMaxYawRate = kPi / 2;                   // rad/s, grid spans [-pi/2, pi/2]

// token = accel_bin * 33 + yaw_bin.
inline int motion_token(int accel_bin, int yaw_bin) { return accel_bin * kMotionBins + yaw_bin; }
double motion_accel(int token);     // m/s^2 of a control token (0..1088)
double motion_yaw_rate(int token);  // rad/s

// What the bicycle model carries from step to step. Speed is signed (along the heading).
struct KinematicState {
  double x = 0, y = 0;
  double heading = 0;
  double speed = 0;
};

// Speed along the heading of a state's velocity; heading from the state.
KinematicState kinematic_state(const StepState& s);

// One bicycle update over dt: v' = v + a dt; psi' = wrap(psi + w dt); the position advances by the mean of the old
// and new speed along the mean of the old and new heading.
KinematicState bicycle_step(const KinematicState& s, double accel, double yaw_rate, double dt = kStepSeconds);
KinematicState apply_motion_token(const KinematicState& s, int token);

struct MotionFit {
  int token = 0;
  KinematicState state;  // the state the token leads to
  double ace = 0;        // its Average Corner Error against the target, metres
};

// The control token whose next pose has the least ACE against `target` for a box of length x width; ties go to
// the bins nearest the grid centre (zero acceleration, zero yaw rate).
MotionFit fit_motion_token(const KinematicState& from, const Pose& target, double length, double width);

// A track tokenized at 2 Hz.
struct MotionTrack {
  // tokens[t]: the token that brought the agent to step t (START where it appears: its first valid step or after a
  // gap); -1 where the agent is invalid. The model's input at step t is tokens[t], its target tokens[t + 1].
  std::vector<int> tokens;
  std::vector<KinematicState> reconstructed;  // the state the tokens reproduce (the true state at START)
  std::vector<double> ace;                    // ACE of the reconstruction at t; 0 at START, NaN where invalid
};

MotionTrack tokenize_motion(std::span<const StepState> steps);

}  // namespace ss
