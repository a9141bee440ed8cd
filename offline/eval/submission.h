// Waymo Open Sim Agents Challenge (WOSAC) submissions: rollouts as the challenge takes them (proto/womd/
// sim_agents_submission.proto), written in shards and read back, so that the challenge, Waymo's own scorer and our
// `eval` all read the same files, whichever model made them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "offline/eval/joint_scene.h"

namespace ss {

// What the challenge requires of a submission (waymo-open-dataset submission_specs.py): 32 rollouts of every object
// valid at frame 10, each 80 frames (8 s at 10 Hz) after it. Our files may hold other counts and lengths (eval
// scores any scenario); challenge_problems says where a submission departs from these.
inline constexpr int kChallengeRollouts = 32;
inline constexpr int kChallengeCurrentFrame = 10;
inline constexpr int kChallengeFutureFrames = 80;
// Scenarios per shard file: with 32 rollouts a scenario takes ~1-3 MB, so a shard stays far below protobuf's 2 GB
// message limit (the reason the challenge shards submissions at all).
inline constexpr int kScenariosPerShard = 32;

// One object's simulated future: frames current + 1 ... at 10 Hz, float32 as the challenge stores them. A Scenario
// Generation submission holds every frame (history included) and the box, validity and type too.
struct SimulatedTrajectory {
  int32_t object_id = 0;
  std::vector<float> x, y, z, heading;
  std::vector<float> length, width, height;  // Scenario Generation: per frame
  std::vector<uint8_t> valid;                // Scenario Generation: per frame
  int32_t object_type = 0;                   // Scenario Generation: a Track.ObjectType value; 0: not given
};

// The parallel rollouts of one scenario; each rollout (a joint scene) holds every sim agent's trajectory.
struct ScenarioRollouts {
  std::string scenario_id;
  std::vector<std::vector<SimulatedTrajectory>> joint_scenes;
};

// The challenge's metadata, copied into every shard. The challenge requires account_name (the e-mail registered at
// waymo.com/open), unique_method_name, authors, affiliation, num_model_parameters ("3M"), the three uses_* answers
// and acknowledge_complies_with_closed_loop_requirement; nothing here fills them in for the user.
struct SubmissionMetadata {
  std::string account_name, unique_method_name, affiliation, description, method_link, num_model_parameters;
  std::vector<std::string> authors, public_model_names;
  bool uses_lidar_data = false, uses_camera_data = false, uses_public_model_pretraining = false;
  bool acknowledge_complies_with_closed_loop_requirement = false;
  bool operator==(const SubmissionMetadata&) const = default;
};

// Reads metadata from a JSON object whose keys are the proto's field names (submission_type excluded: it is always
// SIM_AGENTS_SUBMISSION). An unknown key or a value of the wrong type is an error naming it.
absl::StatusOr<SubmissionMetadata> read_submission_metadata(const std::string& path);

// Eval's rollouts of `s` as a submission. Each scene's objects [0, n) must be the sim agents (sim_agent_tracks(s),
// in that order, as eval builds them); their frames after the current one become the trajectories (rounded to
// float32). Frames after the current one must be valid: a submission has no place for a gap.
absl::StatusOr<ScenarioRollouts> rollouts_from_scenes(const Scenario& s, const std::vector<JointScene>& scenes);

// A rollout file (a complete WOMD scenario, as `simulate` writes it) as one joint scene: every track valid at its
// current frame, its frames after it; a track the rollout leaves invalid after some frame (it left the model's
// region, or the model does not drive its type) moves on at constant velocity from its last state, as in eval.
std::vector<SimulatedTrajectory> trajectories_from_rollout(const Scenario& rollout);

// Rounds a scene's frames after `now` to what a submission holds (x, y, z, heading as float32), so a scene scored
// directly and the same scene read back from its submission give the same numbers.
void round_to_submission(JointScene& scene, int now);

// The joint scenes eval scores for a submitted scenario: the log's sim agents with their logged history, each
// following its submitted trajectory after the current frame, valid throughout, box size held from the current
// frame (the challenge's rule). Errors (starting with `where`) name the rollout and object: a sim agent missing or
// given twice, an object that is not a sim agent, a trajectory of the wrong length, a non-finite value.
absl::StatusOr<std::vector<JointScene>> scenes_from_rollouts(const Scenario& s, const ScenarioRollouts& r,
                                                             const std::string& where);

// Scenario Generation (eval --protocol scenario-gen): each scene's objects are the sim agents (sim_agent_tracks(s)
// order, as scenario_gen.h builds them) with every frame, history included: x, y, z, heading, the box, validity and
// type per trajectory (float32). Every frame must be valid.
absl::StatusOr<ScenarioRollouts> scenegen_rollouts_from_scenes(const Scenario& s, const std::vector<JointScene>& scenes);
// The scenes a Scenario Generation submission holds for `s`, objects in sim_agent_tracks order: each sim agent once,
// every field of every frame given (num_frames values), finite, the type a vehicle, pedestrian or cyclist. Validity
// is the challenge's: every frame of a sim agent (the file's valid field is read but, as in the official scorer, not
// used). Errors start with `where` and name the rollout and object.
absl::StatusOr<std::vector<JointScene>> scenegen_scenes_from_rollouts(const Scenario& s, const ScenarioRollouts& r,
                                                                      const std::string& where);

// How a submission departs from the challenge's requirements (empty when it meets them): rollout counts, current
// frame and future length of each scenario (`scenarios`: the logs, matched by id), and missing metadata.
std::vector<std::string> challenge_problems(const std::vector<ScenarioRollouts>& rollouts,
                                            const std::vector<const Scenario*>& scenarios,
                                            const SubmissionMetadata& metadata);

// The challenge's test set holds history only: its scenarios end at their current frame. Such a scenario padded with
// `future_frames` frames in which no track is valid (timestamps continuing by 0.1 s, no signal states) is rolled out
// for the challenge's 8 s by eval like any other; it has no logged future to be scored against, so its metrics are
// undefined (NaN) and the dataset means leave it out.
Scenario with_empty_future(const Scenario& s, int future_frames);

// Shard file names: <dir>/submission.binproto-00000-of-00003, the challenge's pattern.
std::string submission_shard_path(const std::string& dir, int shard, int shards);
int submission_shard_count(int scenarios);  // ceil(scenarios / kScenariosPerShard), at least 1
// Writes one shard: a SimAgentsChallengeSubmission holding `rollouts` and the metadata (atomically).
absl::Status write_submission_shard(const std::string& path, const std::vector<ScenarioRollouts>& rollouts,
                                    const SubmissionMetadata& metadata);
// write_submission_shard for all `rollouts`, kScenariosPerShard per shard, in order; `dir` is created if absent.
absl::Status write_submission(const std::string& dir, const std::vector<ScenarioRollouts>& rollouts,
                              const SubmissionMetadata& metadata);

struct Submission {
  std::vector<ScenarioRollouts> rollouts;  // in file order, then record order
  SubmissionMetadata metadata;             // the first shard's
};
// Reads submission files: each path a shard file, or a directory whose *.binproto* files are read in name order.
// Refuses a file that is not a SimAgentsChallengeSubmission, a scenario given twice, and a numbered set of shards
// with one missing (e.g. "-00001-of-00003" absent).
absl::StatusOr<Submission> read_submission(const std::vector<std::string>& paths);

}  // namespace ss
