// A session's plain value types: its options, what a tick shows, and the requests a host sends. No Eigen and no
// engine internals, so the public header (engine/scenestreamer.h) can hand them to hosts as they are.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "engine/geometry/geometry.h"
#include "engine/tokens/light.h"
#include "engine/tokens/resample.h"

namespace ss {

// motion, full and densify are the model's modes (the paper's); log and idm are rule baselines (rule_agents.h).
enum class SessionMode : int { motion = 0, full = 1, densify = 2, log = 3, idm = 4 };
const char* session_mode_name(SessionMode m);
// The mode a name (session_mode_name's) stands for; none for another name.
std::optional<SessionMode> session_mode_from_name(const std::string& name);

struct SessionOptions {
  SessionMode mode = SessionMode::motion;
  uint64_t seed = 0;
  // The defaults suit the trained default model (docs/model.md: a sweep on val scenarios cut collision and
  // offroad rates against 0.95 and 1.0, realism within noise of the best).
  double top_p = 0.8;          // motion tokens (nucleus sampling)
  double temperature = 0.7;    // motion and light tokens (a new agent's: 1.0, session.cc)
  int max_agents = 128;        // the cap on agents alive at once (at most the model's agent slots)
  double roi_radius = 100.0;   // metres around the first controlled agent (else the SDC, else the scenario's focus):
                               // agents beyond it retire, new ones spawn within
  int window_steps = 0;        // history window W in steps; 0: the model's window (at most the model's)
  std::vector<int32_t> controlled_ids;  // track ids driven by the caller; empty: the SDC (if the scenario names one)
  bool control_sdc = true;     // with controlled_ids empty: false lets the model drive every agent, the SDC too
  int densify_target = 0;      // densify: agents to reach at the first step
  // A new agent's tokens (type, end of agents, map segment, relative state): the plain softmax by default, as the
  // paper samples every token but motion (docs/model.md, "Full mode"; "Scenario generation" measures other values).
  double placement_temperature = 1.0;
  double placement_top_p = 1.0;
  double placement_clearance = 0.0;  // metres a new agent's box keeps from every other box (0: no overlap)
  // A new agent leaves room to stop: braking at 6 m/s^2 from its velocity, it stops short of every agent moving on
  // at its velocity, and every agent braking so stops short of it (the motion reject sampler's first rule).
  // With agent_counts also: moved back along its velocity over the last second, it stays clear of the SDC's logged
  // boxes (the challenge gives the ego's history, so a generated agent's history must not cross it).
  bool placement_room = false;
  // Full mode: the agents to place per type (vehicles, pedestrians, cyclists), the Scenario Generation Challenge's
  // input. Empty: the model decides how many (its end-of-agents head). Given: the scenario's SDC (valid at the
  // current frame) is taken from the log at the first step, as the challenge gives the ego's history, and is driven
  // by the model after it unless it is controlled; exactly these many agents of each type are placed around it (the
  // end-of-agents and type heads masked); none joins or retires later, so the scene holds the requested agents
  // throughout.
  std::vector<int> agent_counts;
  bool motion_reject = true;   // redraw a control that runs an agent into another or a vehicle off the road
  // Pedestrians may touch: the reject sampler does not test a pedestrian's control against another pedestrian
  // (logged pedestrians walking in groups overlap; docs/model.md, "Scenario generation").
  bool pedestrian_contact = false;
  int tick_hz = 2;             // ticks per second: 2 (a tick is a model step) or 10 (five ticks per model step)
  bool operator==(const SessionOptions&) const = default;
};

// An agent as the caller sees it.
struct AgentView {
  int64_t id = 0;         // public id: the track id for log agents; new ones count up from above the largest track id
  int type = 0;           // 0 vehicle, 1 pedestrian, 2 cyclist
  StepState state;
  bool controlled = false;
  bool entered = false;   // entered at this step
};

struct LightView {
  int64_t lane = 0;       // the lane feature it controls
  LightState state = LightState::unknown;
  Pose stop_point;        // stop point, heading of its lane
};

// Where an agent is on its lane: the nearest lane centre whose direction is within 90 degrees of the agent's heading.
struct LanePosition {
  int64_t lane_id = -1;          // -1: no lane within kLaneMaxDistance (engine/sim/events.h)
  double s = 0;                  // metres along the lane from its first point to the agent's projection
  double offset = 0;             // signed lateral distance of the centre, + left of the lane direction
  double heading_error = 0;      // agent heading minus lane direction, [-pi, pi)
  Vec2 direction;                // unit lane direction at the projection
};

// What happened to one controlled agent at a tick (the rules are in engine/sim/events.h). RL clients build rewards
// and terminations from these, so the rules live in the engine once instead of being guessed by every client.
struct AgentEvents {
  int64_t agent_id = 0;
  std::vector<int64_t> overlapping;  // ids of agents whose boxes overlap this agent's box, ascending
  double road_edge_distance = 0;     // the most off-road box corner's signed distance to the road edge (+: off);
                                     // NaN when the map has no road edge
  bool off_road = false;             // road_edge_distance > 0
  bool ran_red_light = false;        // the centre crossed a red light's stop line since the previous tick
  int64_t red_light_lane = -1;       // that light's lane
  LanePosition lane;
  double progress = 0;               // the centre's displacement since the previous tick along its lane's
                                     // direction (at the new position, else the old); 0 off every lane
};

struct StepResult {
  int step = 0;                 // model step (2 Hz) since the scenario's first frame
  double time = 0;              // seconds: step * 0.5
  std::vector<AgentView> agents;
  std::vector<LightView> lights;
  std::vector<int64_t> left;    // agents retired at this step
  // A tick's result only (Session::tick): each controlled agent's events, measured from the tick before. Empty in
  // views (Session::current, tick_view) and in Session::step's results (the offline tools do not need them).
  std::vector<AgentEvents> events;
};

// A controlled agent's pose at the next tick.
struct ControlInput {
  int64_t agent_id = 0;
  double x = 0, y = 0, heading = 0;
  std::optional<double> speed;  // along the heading; derived from the displacement when absent
};

struct InjectRequest {
  int count = 0;                  // sample this many new agents (0 when `state` is given)
  std::optional<int> type;        // 0 vehicle, 1 pedestrian, 2 cyclist; sampled when absent
  std::optional<Vec2> near;       // spawn within `near_radius` of this point
  double near_radius = 20.0;
  std::optional<int> segment;     // spawn on this map segment (index among the session's map tokens)
  std::optional<StepState> state; // insert exactly this agent (with `type`, default vehicle)
};

struct StateForceRequest {
  std::vector<std::pair<int64_t, StepState>> agents;     // agent id -> state at the next step (a teleport)
  std::vector<std::pair<int64_t, LightState>> lights;    // lane id -> state at the next step
};

// The session state format's magic (session_save): its last character is the format's version. Version 2 added the
// tick clock (tick rate, tick, the poses pushed since the last model step); version 3 is the same state as a protobuf
// message (proto/state/session_state.proto) behind a hash.
inline constexpr char kSessionStateMagic[9] = "SSSESSN3";

}  // namespace ss
