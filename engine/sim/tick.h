// Ticks faster than the model's 2 Hz steps (10 Hz clients): between two model steps the background agents are
// advanced at their velocity of the last model step, in 0.1 s sub-steps, so they move every tick; controlled agents
// show the pose their client pushed. The model itself still reacts at 2 Hz, as trained. The next model step then
// replaces the extrapolation with sampled motion (a small jump at most: 0.5 s of acceleration).
#pragma once

#include <vector>

#include "engine/sim/session.h"

namespace ss {

// The view `sub_tick` ticks (0 < sub_tick < ticks_per_step) after the model step `at_step`. `pushed` are the latest
// poses of controlled agents. Entered/left lists are empty between steps (they happen at model steps).
StepResult tick_between_steps(const StepResult& at_step, int sub_tick, int ticks_per_step,
                              const std::vector<ControlInput>& pushed);

}  // namespace ss
