// What the realism features read: one scene (the log, or one rollout) as boxes at 10 Hz, every object over every
// frame of its scenario (history included), like the WOSAC "joint scene" with the logged history prepended.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/scenario/scenario.h"

namespace ss {

inline constexpr double kEvalFrameSeconds = 0.1;  // WOSAC scores 10 Hz trajectories

struct BoxState {
  double x = 0, y = 0, z = 0;  // box centre, metres
  double heading = 0;          // radians
  double length = 0, width = 0, height = 0;
  bool valid = false;
};

struct SceneObject {
  int64_t id = 0;
  ObjectType type = ObjectType::unset;
  std::vector<BoxState> states;  // one per frame
};

struct JointScene {
  std::vector<SceneObject> objects;  // all with the same number of frames
  int num_frames() const { return objects.empty() ? 0 : static_cast<int>(objects[0].states.size()); }
};

BoxState box_state(const ObjectState& s);

// Who drives the SDC in an evaluation. model: the policy, like every other agent (WOSAC's rule: the simulation
// drives every agent it is scored on). log: the SDC follows its logged poses, as an RL client's ego would, and is
// therefore left out of the evaluated objects.
enum class SdcRule { model, log };
const char* sdc_rule_name(SdcRule r);

// The objects the realism metrics score.
struct EvaluatedObjects {
  std::vector<int> tracks;         // track indices, sorted by object id (WOSAC's order)
  bool named_by_scenario = false;  // true: the SDC and tracks_to_predict; false: every track valid at the current frame
};
// The SDC and the tracks_to_predict valid at the current frame when the scenario names tracks to predict; otherwise
// (older JSON files, the 20 s files) every track valid at the current frame. Under SdcRule::log the SDC is left out.
// May be empty (a scenario whose only named track is the SDC, under SdcRule::log).
EvaluatedObjects evaluated_objects(const Scenario& s, SdcRule sdc = SdcRule::model);

// Every track valid at the current frame, in track order: the WOSAC sim agents (all are obstacles for the
// interaction features).
std::vector<int> sim_agent_tracks(const Scenario& s);

// The log of `tracks` as a joint scene: logged poses and validity. After the current frame the box size is the
// current frame's, held (WOSAC does the same for the log and the rollouts).
JointScene log_scene(const Scenario& s, const std::vector<int>& tracks);

// Position of each of `tracks` (indices into s.tracks) within `tracks_in_scene`; -1 when absent.
std::vector<int> scene_indices(const std::vector<int>& tracks_in_scene, const std::vector<int>& tracks);

}  // namespace ss
