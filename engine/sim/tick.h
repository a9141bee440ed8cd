// Ticks faster than the model's 2 Hz steps (10 Hz clients). The model still reacts at 2 Hz, as trained, but the
// (acceleration, yaw rate) control each background agent sampled at the last step boundary already fixes where the
// next step puts it, so tick k of n between two steps shows that control integrated over t = 0.5 k / n seconds with
// the step's own kinematic rule (docs/design.md section 5) evaluated at dt = t: speed v + a t, heading psi + w t, position
// advanced by the mean of the old and new speed along the mean of the old and new heading. At k = n this is exactly
// the next step's pose, so background agents move every tick along the path the step then takes, without a jump.
// (Chaining n updates of 0.1 s instead would bend towards an arc and miss the step's single-chord end point by about
// 2.5 % of the step's travel at the largest yaw rate: 0.12 m at 10 m/s.)
//
// Agents whose next step is not their sampled control keep the plain behaviour:
// - controlled agents show the pose their client pushed last, or their step pose when none was pushed;
// - an agent with a pending StateForce moves on at its velocity of the last step: the force teleports it at the next
//   step, not before;
// - an agent without a sampled control (none in practice: every agent samples one at each step) holds its speed
//   along its heading, which is what step() does with it.
#pragma once

#include <vector>

#include "engine/sim/session.h"

namespace ss {

// The view `sub_tick` of `ticks_per_step` ticks after the session's current model step (0 < sub_tick <
// ticks_per_step between steps; sub_tick == ticks_per_step predicts the next step's background agents). `pushed` are
// the latest poses of controlled agents. Entered/left lists are empty between steps (they happen at model steps).
StepResult tick_between_steps(const Session& session, int sub_tick, int ticks_per_step,
                              const std::vector<ControlInput>& pushed);

}  // namespace ss
