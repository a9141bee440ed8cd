// Cuts a recorded SUMO run into WOMD scenarios: 9.1 s windows (91 frames at 10 Hz, current frame 10) around moving
// ego vehicles, each with the agents seen within a radius of the ego, the map around it and its signal states.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "offline/dataset/sumo_events.h"
#include "offline/dataset/sumo_fcd.h"
#include "offline/dataset/sumo_map.h"
#include "engine/scenario/scenario.h"

namespace ss {

struct WindowOptions {
  int frames = 91;
  int current_frame = 10;
  double stride = 5.0;          // seconds between window starts
  double radius = 100.0;        // agents are tracked while within this distance of the ego (metres)
  double map_radius = 150.0;    // map features with a point this close to the ego's current position
  int egos_per_window = 4;      // scenarios cut from one window, each around another ego
  double ego_separation = 100.0;  // egos of one window at least this far apart at the current frame
  double min_ego_speed = 1.0;   // m/s at the current frame: the ego is moving
  int max_tracks = 128;
  int max_tracks_to_predict = 8;
  // Motion no real agent makes, which SUMO produces now and then (a vehicle whipping round a kinked junction lane at
  // speed, a position jump SUMO did not report): windows holding it are dropped like those with teleports.
  double jump_distance = 5.0;           // metres in one frame (50 m/s)
  double max_lateral_acceleration = 30; // m/s^2 (3 g), speed x yaw rate, vehicles and cyclists
};

struct WindowCut {
  std::vector<Scenario> scenarios;
  int windows = 0;              // window starts tried
  int dropped_collision = 0;    // scenarios dropped: an agent collided in the window
  int dropped_teleport = 0;     // ... an agent teleported in the window (SUMO's report)
  int dropped_implausible = 0;  // ... an agent jumped or turned impossibly fast in the window
};

// `id_prefix` starts every scenario id; `seed` drives the choice of egos. Deterministic for equal inputs.
WindowCut cut_windows(const SumoMap& map, const FcdRecording& fcd, const SignalTimeline& signals,
                      const std::vector<Incident>& incidents, const WindowOptions& options, uint64_t seed,
                      const std::string& id_prefix);

}  // namespace ss
