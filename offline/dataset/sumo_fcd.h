// SUMO floating-car data (--fcd-output) as agent tracks in WOMD conventions.
//   heading  SUMO's angle is in degrees, clockwise from north; WOMD's heading is in radians, counter-clockwise from
//            east: heading = wrap(radians(90 - angle)).
//   position SUMO reports a vehicle (bicycles included) at the centre of its FRONT bumper; WOMD tracks box centres:
//            centre = front - length/2 (cos heading, sin heading). A person's position is its centre.
//   velocity speed along the heading.
#pragma once

#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"

namespace ss {

// What a SUMO vType becomes: its WOMD object type and box size.
struct AgentKind {
  ObjectType type = ObjectType::vehicle;
  float length = 0, width = 0, height = 0;
};
using AgentKinds = std::unordered_map<std::string, AgentKind>;  // vType id -> kind
using AgentTypes = std::unordered_map<std::string, std::string>;  // agent id -> vType id

struct FcdState {
  double x = 0, y = 0;  // box centre
  float heading = 0;
  float speed = 0;
  bool valid = false;
};

struct FcdTrack {
  std::string id;       // SUMO vehicle or person id
  AgentKind kind;
  int first_frame = 0;  // frame of states[0]
  std::vector<FcdState> states;  // frames first_frame .. first_frame + states.size() - 1

  const FcdState* at(int frame) const {
    const int k = frame - first_frame;
    return k >= 0 && k < static_cast<int>(states.size()) && states[k].valid ? &states[k] : nullptr;
  }
};

struct FcdRecording {
  double begin = 0;   // time of frame 0, seconds
  double step = 0.1;  // seconds between frames
  int frames = 0;
  std::vector<FcdTrack> tracks;  // ordered by id

  double time_of(int frame) const { return begin + frame * step; }
  // The frame nearest `t` (may lie outside 0..frames-1).
  int frame_of(double t) const;
};

double heading_from_sumo_angle(double angle_degrees);
Vec2 centre_from_front(Vec2 front, double heading, double length);

// Parses an FCD file's text. Every vehicle and person needs x, y, angle and speed, and a vType: its `type`
// attribute, or else its entry in `types` (SUMO 1.15 writes no type for persons). The vType must be in `kinds`:
// an unknown one is an error rather than a box of made-up size. Timesteps must be `step` apart.
absl::StatusOr<FcdRecording> parse_fcd(std::string_view xml, const std::string& where, const AgentKinds& kinds,
                                       const AgentTypes& types, double step);

}  // namespace ss
