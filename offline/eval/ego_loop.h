// The closed-loop ego benchmark: the SDC driven by a scripted policy the way a client drives it (its pose pushed at
// every 2 Hz tick through Session::tick, the path StepScene takes), and what happened to it: collisions split by who
// ran into whom, off road, and collisions among the background agents. docs/closed-loop.md has the figures.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/geometry/geometry.h"
#include "engine/scenario/scenario.h"
#include "engine/sim/rule_agents.h"
#include "engine/sim/session.h"

namespace ss {

// log: the SDC's logged poses. slow / fast: its logged path at 0.6x / 1.3x the logged speed profile (the log's
// progress at 0.6 or 1.3 times the elapsed time; past the log's end the path goes on straight at the last speed).
// cruise: the Python package's cruise rule (python/scenestreamer/policies.py), the same rule and constants.
enum class EgoPolicy { log, slow, fast, cruise };
const char* ego_policy_name(EgoPolicy p);
std::optional<EgoPolicy> ego_policy_from_name(const std::string& name);

// The ego's next pose under a policy. `scenario` is the whole log (the policies read the SDC's logged future; the
// session is not given it).
class EgoDriver {
 public:
  static absl::StatusOr<EgoDriver> create(const Scenario& scenario, EgoPolicy policy);
  // The pose at model step `next_step`, given the tick the session shows now. None: the policy has no pose there
  // (the log ego past its log), and the session keeps the ego's last control.
  std::optional<ControlInput> next(const StepResult& now, int next_step) const;

 private:
  EgoPolicy policy_ = EgoPolicy::log;
  const Scenario* scenario_ = nullptr;
  int64_t id_ = -1;
  LoggedPath path_;
  std::vector<double> frame_s_;      // the log's arc length at each frame (held over invalid frames)
  std::vector<double> frame_speed_;  // the log's speed at each frame
  std::vector<Vec2> lane_points_, lane_dirs_;  // cruise: lane centres every 2 m, with their directions
};

// The cruise rule on an ego at `ego` among `others`: (acceleration m/s^2, yaw rate rad/s). Lane points and
// directions are global; only the 64 nearest within 40 m are read, and agents among the 16 nearest within 60 m, as
// the package's observation holds them.
std::pair<double, double> cruise_action(const StepState& ego, const std::vector<StepState>& others,
                                        const std::vector<Vec2>& lane_points, const std::vector<Vec2>& lane_dirs);
// The pose after 0.5 s under (acceleration, yaw rate), by the rule the Python client's advance() applies.
ControlInput advance_pose(int64_t id, const StepState& s, double accel, double yaw_rate);

// Who ran into whom when another agent's box first overlaps the ego's. From the two boxes at the step of contact
// (and their headings): the striker is the agent whose front-centre point lies deeper in (or nearer to) the other's
// box (within a centimetre, as head-on, the faster one). Rear-end: the other is the striker and the headings are within 45 degrees (it drove into the ego from
// behind). Ego at fault: the ego is the striker (it drove into the other, at any angle). Side: the other is the
// striker at more than 45 degrees (a crossing or side impact).
enum class EgoCollision { none, rear_end, ego_at_fault, side };
const char* ego_collision_name(EgoCollision c);
EgoCollision classify_ego_collision(const StepState& ego, const StepState& other);

// One episode's outcome. An overlap is a collision when it begins between two agents that were both present, apart,
// at the step before: overlaps at the first step, and agents that enter overlapping (the log has both), are not.
struct EgoOutcome {
  int steps = 0;
  EgoCollision collision = EgoCollision::none;  // the episode's first ego collision
  int collision_step = -1;
  int64_t collision_with = -1;
  bool off_road = false;            // the ego's box left the road at some tick (vehicles only)
  int background_agents = 0;        // distinct agents other than the ego that took part
  int background_collided = 0;      // of them, those whose box newly overlapped another background agent's
};

// Runs one episode: a session created from `session_scenario` (history only for the model modes; the whole log for
// the rule modes), the SDC controlled and pushed by `driver` at every tick, for `steps` 2 Hz steps. Returns the
// steps from the current one on, as run_model_rollout does, and the outcome.
absl::StatusOr<std::vector<StepResult>> run_ego_episode(std::shared_ptr<const Model> model,
                                                        std::shared_ptr<const Scenario> session_scenario,
                                                        std::shared_ptr<const MapContext> map,
                                                        const SessionOptions& options, const EgoDriver& driver,
                                                        int steps, EgoOutcome* outcome);

// The outcome measured on given steps (the ego is `ego_id`; its overlaps from box tests).
EgoOutcome ego_outcome(const std::vector<StepResult>& steps, int64_t ego_id, bool ego_off_road);

}  // namespace ss
