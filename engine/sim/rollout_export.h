// A rollout as a WOMD Scenario: 2 Hz model steps upsampled to 10 Hz, so every WOMD tool (and `render`) reads it.
#pragma once

#include <vector>

#include "engine/scenario/scenario.h"
#include "engine/sim/session.h"

namespace ss {

// `steps` are consecutive results of one session (the first is usually Session::current() after creation).
// The output keeps the source's map and id (suffixed "-rollout"), holds one track per agent ever present (valid only
// while present), the lights as signal states with their stop points, the first controlled agent as the SDC, and
// timestamps from the first step's time at 0.1 s per frame; current_time_index 0.
Scenario rollout_to_scenario(const Scenario& source, const std::vector<StepResult>& steps);

}  // namespace ss
