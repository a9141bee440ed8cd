// Traffic-light tokens: the model's 4 light states (paper appendix E).
#pragma once

#include <cstdint>

#include "engine/scenario/scenario.h"

namespace ss {

enum class LightState : uint8_t { unknown = 0, green = 1, yellow = 2, red = 3 };
inline constexpr int kNumLightStates = 4;

// The 9 WOMD lane states onto 4: arrows and flashing lights count as their colour (a flashing red is a stop).
LightState light_state_from_womd(SignalState s);
const char* light_state_name(LightState s);

}  // namespace ss
