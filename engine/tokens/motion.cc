#include "engine/tokens/motion.h"

#include <cmath>
#include <cstdlib>
#include <limits>

namespace ss {
namespace {

double grid_value(int bin, double max) { return -max + 2 * max * bin / (kMotionBins - 1); }

// A tie-break far below any real error (1e-9 m per bin from the centre) so that equal candidates resolve to the
// smallest control deterministically.
constexpr double kCentrePreference = 1e-9;

}  // namespace

double motion_accel(int token) { return grid_value(token / kMotionBins, kMaxAccel); }
double motion_yaw_rate(int token) { return grid_value(token % kMotionBins, kMaxYawRate); }

KinematicState kinematic_state(const StepState& s) {
  return {s.x, s.y, s.heading, s.vx * std::cos(s.heading) + s.vy * std::sin(s.heading)};
}

KinematicState bicycle_step(const KinematicState& s, double accel, double yaw_rate, double dt) {
  KinematicState n;
  n.speed = s.speed + accel * dt;
  n.heading = wrap_angle(s.heading + yaw_rate * dt);
  double mean_heading = circular_mean2(s.heading, n.heading);
  double mean_speed = 0.5 * (s.speed + n.speed);
  n.x = s.x + mean_speed * std::cos(mean_heading) * dt;
  n.y = s.y + mean_speed * std::sin(mean_heading) * dt;
  return n;
}

KinematicState apply_motion_token(const KinematicState& s, int token) {
  return bicycle_step(s, motion_accel(token), motion_yaw_rate(token));
}

MotionFit fit_motion_token(const KinematicState& from, const Pose& target, double length, double width) {
  const Box target_box{target, length, width};
  const auto target_corners = box_corners(target_box);
  // Corner offsets of the box in its own frame, matching box_corners' order.
  const double hl = length / 2, hw = width / 2;
  const Vec2 offsets[4] = {{hl, hw}, {-hl, hw}, {-hl, -hw}, {hl, -hw}};

  MotionFit best;
  double best_cost = std::numeric_limits<double>::infinity();
  for (int wb = 0; wb < kMotionBins; ++wb) {
    // Everything that depends only on the yaw rate is computed once per column of the grid.
    KinematicState unit = bicycle_step({0, 0, from.heading, 0}, 0, grid_value(wb, kMaxYawRate));
    const double c = std::cos(unit.heading), s = std::sin(unit.heading);
    const double mean_heading = circular_mean2(from.heading, unit.heading);
    const double mc = std::cos(mean_heading), ms = std::sin(mean_heading);
    for (int ab = 0; ab < kMotionBins; ++ab) {
      const double accel = grid_value(ab, kMaxAccel);
      const double travel = (from.speed + 0.5 * accel * kStepSeconds) * kStepSeconds;
      const double x = from.x + travel * mc, y = from.y + travel * ms;
      double ace = 0;
      for (int k = 0; k < 4; ++k) {
        double cx = x + c * offsets[k].x - s * offsets[k].y;
        double cy = y + s * offsets[k].x + c * offsets[k].y;
        ace += std::hypot(cx - target_corners[k].x, cy - target_corners[k].y);
      }
      ace /= 4;
      const double cost = ace + kCentrePreference * (std::abs(ab - kMotionBins / 2) + std::abs(wb - kMotionBins / 2));
      if (cost < best_cost) {
        best_cost = cost;
        best.token = motion_token(ab, wb);
      }
    }
  }
  // The search's arithmetic is reordered for speed; the state comes from the one update rule the rollout uses.
  best.state = apply_motion_token(from, best.token);
  best.ace = average_corner_error({{best.state.x, best.state.y, best.state.heading}, length, width}, target_box);
  return best;
}

MotionTrack tokenize_motion(std::span<const StepState> steps) {
  MotionTrack out;
  out.tokens.assign(steps.size(), -1);
  out.reconstructed.assign(steps.size(), KinematicState{});
  out.ace.assign(steps.size(), std::numeric_limits<double>::quiet_NaN());
  for (size_t t = 0; t < steps.size(); ++t) {
    const StepState& s = steps[t];
    if (!s.valid) continue;
    if (t == 0 || !steps[t - 1].valid) {
      out.tokens[t] = kMotionStart;
      out.reconstructed[t] = kinematic_state(s);
      out.ace[t] = 0;
      continue;
    }
    MotionFit fit = fit_motion_token(out.reconstructed[t - 1], {s.x, s.y, s.heading}, s.length, s.width);
    out.tokens[t] = fit.token;
    out.reconstructed[t] = fit.state;
    out.ace[t] = fit.ace;
  }
  return out;
}

}  // namespace ss
