#include "engine/tokens/light.h"

namespace ss {

LightState light_state_from_womd(SignalState s) {
  switch (s) {
    case SignalState::arrow_go:
    case SignalState::go: return LightState::green;
    case SignalState::arrow_caution:
    case SignalState::caution:
    case SignalState::flashing_caution: return LightState::yellow;
    case SignalState::arrow_stop:
    case SignalState::stop:
    case SignalState::flashing_stop: return LightState::red;
    case SignalState::unknown: break;
  }
  return LightState::unknown;
}

const char* light_state_name(LightState s) {
  switch (s) {
    case LightState::unknown: return "unknown";
    case LightState::green: return "green";
    case LightState::yellow: return "yellow";
    case LightState::red: return "red";
  }
  return "invalid";
}

}  // namespace ss
