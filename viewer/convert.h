// What the viewer's page reads, as JSON: a tick of a watched session, a scenario's map, a rollout file. The page
// (viewer/web/src/types.ts) is the other half of these formats; compact arrays keep a 128-agent tick near 6 kB.
//
//   agent: [id, type, x, y, heading, length, width, speed, flags]   type 0 vehicle, 1 pedestrian, 2 cyclist, 3 other
//   light: [lane, x, y, heading, state]                              state 0 unknown, 1 green, 2 yellow, 3 red
//   map feature: {"id", "type", "subtype", "pts": [x0, y0, x1, y1, ...]}   type as MapFeatureType in the proto
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "engine/scenario/scenario.h"
#include "engine/sim/events.h"
#include "nlohmann/json.hpp"
#include "scenestreamer/v1/simulator.pb.h"

namespace viewer {

namespace pb = scenestreamer::v1;

// Agent flags (the last field of an agent).
enum AgentFlag : int {
  kControlled = 1,   // driven by a client (the ego)
  kEntered = 2,      // entered at this tick
  kOverlap = 4,      // its box overlaps another agent's (the engine's events, engine/sim/events.h)
  kOffRoad = 8,      // a box corner beyond the road edge (vehicles only: pedestrians walk off the road)
  kRedLight = 16,    // its centre crossed a red light's stop line since the previous tick
};

// The engine's events of every agent of `after` against `before` (the previous tick; empty at the first), as flags
// by agent id. Every agent is measured, not only the controlled ones the server reports in StepScene: the viewer
// flags what happens to model agents too.
std::map<int64_t, int> event_flags(const ss::EventMap& map, const ss::StepResult& before, const ss::StepResult& after);

// A tick from the server as the engine's view (for event_flags).
ss::StepResult step_result_of(const pb::Tick& tick);

// {"type": "tick", "tick", "step", "time", "agents", "lights", "left"} with each agent's flags.
nlohmann::json tick_json(const pb::Tick& tick, const std::map<int64_t, int>& flags);

// A session's row in the page's list: id, scenario, mode, tick, agents, controllers, tick rate.
nlohmann::json session_json(const pb::SessionInfo& info);

// The map features of a scenario.
nlohmann::json map_json(const std::vector<ss::MapFeature>& features);

// A scenario file's scenarios for the page's offline mode: per scenario its id, timestamps, current frame, SDC, map,
// tracks (one agent array or null per frame, flags from the engine's events between consecutive frames) and the
// lights of every frame. `log`, when given, is the logged scenario of the same id: its tracks are the ghost of the
// logged future.
nlohmann::json scenario_json(const ss::Scenario& s, const ss::Scenario* log);

}  // namespace viewer
