// What a SUMO run reports besides positions: traffic-light switches (the SaveTLSSwitchStates output), collisions
// (--collision-output) and teleports (warnings in the log). A window of a run that holds a collision or a teleport of
// one of its agents is not realistic driving, and the generator drops it.
#pragma once

#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "absl/status/statusor.h"

namespace ss {

// Each traffic light's state string from each switch on, in time order.
class SignalTimeline {
 public:
  void add(const std::string& tl, double time, std::string state);
  // The state in force at `t` (the last switch at or before it), nullptr before the first recorded switch.
  const std::string* state_at(const std::string& tl, double t) const;
  size_t num_lights() const { return switches_.size(); }

 private:
  struct Switch {
    double time;
    std::string state;
  };
  std::unordered_map<std::string, std::vector<Switch>> switches_;
};

// Parses <tlsState time=".." id=".." state=".."/> elements (SUMO's SaveTLSSwitchStates and SaveTLSStates output).
absl::StatusOr<SignalTimeline> parse_signal_switches(std::string_view xml, const std::string& where);

// An agent's collision or teleport at a time.
struct Incident {
  std::string agent;
  double time = 0;
  bool teleport = false;  // false: a collision
};

// Parses <collision time=".." collider=".." victim=".."/>: one incident for each of the two agents.
absl::StatusOr<std::vector<Incident>> parse_collisions(std::string_view xml, const std::string& where);

// Teleports in a SUMO log: lines such as
//   Warning: Teleporting vehicle 'v3'; waited too long (jam), lane='e_0', time=312.40.
//   Warning: Vehicle 'v3' ends teleporting on edge 'f', time=330.00.
//   Warning: Teleporting person 'p1'; waited too long, from edge 'a', time=305.10.
// give an incident for the quoted agent at the time (both the start and the end of a teleport).
std::vector<Incident> parse_teleports(std::string_view log);

}  // namespace ss
