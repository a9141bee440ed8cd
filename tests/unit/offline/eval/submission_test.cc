// WOSAC submissions: eval's rollouts -> shard files -> read back -> the very scenes eval scored; every malformed
// submission refused with a message naming the scenario, rollout and object; and a rollout exported as a complete
// WOMD scenario (rollout_to_scenario) keeps the log up to its current frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include <unistd.h>

#include "offline/eval/baselines.h"
#include "offline/eval/evaluate.h"
#include "offline/eval/model_rollout.h"
#include "offline/eval/submission.h"
#include "engine/model/weights.h"
#include "engine/scenario/read.h"
#include "engine/sim/rollout_export.h"

namespace ss {
namespace {

namespace fs = std::filesystem;

std::shared_ptr<const Scenario> load(const std::string& path) {
  auto s = read_scenarios(std::string(SS_DATA_DIR) + path);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::make_shared<const Scenario>((*s)[0]);
}

std::string temp_dir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("ss_submission_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

// Two distinct rollouts of every sim agent: constant velocity, and constant velocity at half speed.
std::vector<JointScene> two_rollouts(const Scenario& s) {
  const std::vector<int> tracks = sim_agent_tracks(s);
  JointScene a = constant_velocity_scene(s, tracks), b = log_scene(s, tracks);
  for (size_t k = 0; k < tracks.size(); ++k) {
    const ObjectState& o = s.tracks[tracks[k]].states[s.current_time_index];
    extend_constant_velocity(b.objects[k].states, s.current_time_index, o.vx / 2, o.vy / 2);
  }
  return {a, b};
}

TEST(Submission, WrittenAndReadBackGivesTheScoredScenes) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  std::vector<JointScene> scenes = two_rollouts(*s);
  for (JointScene& j : scenes) round_to_submission(j, s->current_time_index);
  auto rollouts = rollouts_from_scenes(*s, scenes);
  ASSERT_TRUE(rollouts.ok()) << rollouts.status();
  ASSERT_EQ(rollouts->joint_scenes.size(), 2u);
  EXPECT_EQ(rollouts->joint_scenes[0].size(), sim_agent_tracks(*s).size());
  EXPECT_EQ(rollouts->joint_scenes[0][0].x.size(), static_cast<size_t>(kChallengeFutureFrames));

  const std::string dir = temp_dir("roundtrip");
  SubmissionMetadata m;
  m.account_name = "someone@example.org", m.authors = {"A", "B"}, m.num_model_parameters = "3M";
  m.uses_camera_data = true;
  ASSERT_TRUE(write_submission(dir, {*rollouts}, m).ok());
  EXPECT_TRUE(fs::exists(dir + "/submission.binproto-00000-of-00001"));
  auto read = read_submission({dir});
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->metadata, m);
  ASSERT_EQ(read->rollouts.size(), 1u);
  auto back = scenes_from_rollouts(*s, read->rollouts[0], dir);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), 2u);
  for (size_t r = 0; r < 2; ++r)
    for (size_t k = 0; k < scenes[r].objects.size(); ++k)
      for (int f = 0; f < s->num_frames(); ++f) {
        const BoxState &a = scenes[r].objects[k].states[f], &b = (*back)[r].objects[k].states[f];
        ASSERT_EQ(a.valid, b.valid) << r << " " << k << " " << f;
        if (!a.valid) continue;
        ASSERT_EQ(a.x, b.x) << r << " " << k << " " << f;
        ASSERT_EQ(a.y, b.y);
        ASSERT_EQ(a.z, b.z);
        ASSERT_EQ(a.heading, b.heading);
        ASSERT_EQ(a.length, b.length);
        ASSERT_EQ(a.width, b.width);
      }

  // Scored from the files, the same numbers as scored directly (evaluate_scenario with the scenes given).
  EvalOptions direct;
  direct.policy = EvalPolicy::submission;
  auto e1 = evaluate_scenario(s, direct, nullptr, nullptr, &scenes);
  auto e2 = evaluate_scenario(s, direct, nullptr, nullptr, &*back);
  ASSERT_TRUE(e1.ok() && e2.ok());
  EXPECT_EQ(e1->realism.meta, e2->realism.meta);
  EXPECT_EQ(e1->realism.min_ade, e2->realism.min_ade);
  fs::remove_all(dir);
}

TEST(Submission, EvalWithSubmissionPrecisionScoresWhatItWrites) {
  const auto s = load("/womd/json/val/womd_27d205cc.json");
  EvalOptions o;
  o.policy = EvalPolicy::constant_velocity;
  o.rollouts = 2;
  o.submission_precision = true;
  std::vector<JointScene> scenes;
  auto direct = evaluate_scenario(s, o, nullptr, nullptr, nullptr, &scenes);
  ASSERT_TRUE(direct.ok()) << direct.status();
  auto rollouts = rollouts_from_scenes(*s, scenes);
  ASSERT_TRUE(rollouts.ok()) << rollouts.status();
  auto back = scenes_from_rollouts(*s, *rollouts, "test");
  ASSERT_TRUE(back.ok()) << back.status();
  EvalOptions from_files;
  from_files.policy = EvalPolicy::submission;
  auto scored = evaluate_scenario(s, from_files, nullptr, nullptr, &*back);
  ASSERT_TRUE(scored.ok()) << scored.status();
  EXPECT_EQ(direct->realism.meta, scored->realism.meta);
  for (int f = 0; f < kNumRealismFeatures; ++f)
    EXPECT_EQ(direct->realism.likelihood[f], scored->realism.likelihood[f]) << f;
  EXPECT_EQ(direct->realism.min_ade, scored->realism.min_ade);
  EXPECT_EQ(direct->motion_all.ade_avg, scored->motion_all.ade_avg);
}

TEST(Submission, MalformedRolloutsAreRefusedNamingWhat) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  auto good = rollouts_from_scenes(*s, two_rollouts(*s));
  ASSERT_TRUE(good.ok());
  auto expect_error = [&](ScenarioRollouts r, const std::string& needle) {
    auto scenes = scenes_from_rollouts(*s, r, "sub");
    ASSERT_FALSE(scenes.ok()) << needle;
    EXPECT_NE(scenes.status().message().find(needle), std::string::npos) << scenes.status().message();
    EXPECT_NE(scenes.status().message().find("sub: scenario " + s->id), std::string::npos) << scenes.status().message();
  };
  const int32_t first = good->joint_scenes[1][0].object_id;
  {
    ScenarioRollouts r = *good;
    r.joint_scenes[1].erase(r.joint_scenes[1].begin());
    expect_error(r, "rollout 1: sim agent " + std::to_string(first) + " (valid at the current frame) is missing");
  }
  {
    ScenarioRollouts r = *good;
    r.joint_scenes[1].push_back(r.joint_scenes[1][0]);
    expect_error(r, "object " + std::to_string(first) + " is given twice");
  }
  {
    ScenarioRollouts r = *good;
    r.joint_scenes[0][0].heading.pop_back();
    expect_error(r, "79 heading values; the scenario has 80 frames after its current frame 10");
  }
  {
    ScenarioRollouts r = *good;
    r.joint_scenes[0][0].y[5] = std::nanf("");
    expect_error(r, "non-finite");
  }
  {
    ScenarioRollouts r = *good;
    r.joint_scenes[0][0].object_id = 99999999;
    expect_error(r, "object 99999999 is not in the scenario");
  }
  {
    // A track of the log that is not valid at the current frame is not a sim agent.
    const std::vector<int> agents = sim_agent_tracks(*s);
    const std::set<int> sim(agents.begin(), agents.end());
    int other = -1;
    for (size_t i = 0; i < s->tracks.size() && other < 0; ++i)
      if (!sim.count(static_cast<int>(i))) other = static_cast<int>(i);
    ASSERT_GE(other, 0);
    ScenarioRollouts r = *good;
    r.joint_scenes[0][0].object_id = s->tracks[other].id;
    expect_error(r, "is not valid at the current frame, so it is not a sim agent");
  }
  {
    ScenarioRollouts r = *good;
    r.joint_scenes.clear();
    expect_error(r, "has no rollout");
  }
  // A scene with a gap cannot become a submission.
  std::vector<JointScene> scenes = two_rollouts(*s);
  scenes[0].objects[2].states[40].valid = false;
  auto gap = rollouts_from_scenes(*s, scenes);
  ASSERT_FALSE(gap.ok());
  EXPECT_NE(gap.status().message().find("has no state at frame 40"), std::string::npos) << gap.status().message();
}

TEST(Submission, FilesAreCheckedWhenRead) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  auto r = rollouts_from_scenes(*s, two_rollouts(*s));
  ASSERT_TRUE(r.ok());
  const std::string dir = temp_dir("files");
  // A numbered set with a shard missing.
  ASSERT_TRUE(write_submission_shard(submission_shard_path(dir, 0, 2), {*r}, {}).ok());
  auto missing = read_submission({dir});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("submission.binproto-00001-of-00002 is missing (1 of 2 shards given)"),
            std::string::npos)
      << missing.status().message();
  // The same scenario in two shards.
  ASSERT_TRUE(write_submission_shard(submission_shard_path(dir, 1, 2), {*r}, {}).ok());
  auto twice = read_submission({dir});
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.status().message().find("scenario " + s->id + " is given twice"), std::string::npos)
      << twice.status().message();
  // Not a submission at all.
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir + "/junk.binproto") << "\xff\xff\xff not a proto";
  auto junk = read_submission({dir + "/junk.binproto"});
  ASSERT_FALSE(junk.ok());
  EXPECT_NE(junk.status().message().find("junk.binproto: not a SimAgentsChallengeSubmission"), std::string::npos)
      << junk.status().message();
  auto none = read_submission({dir + "/absent"});
  EXPECT_FALSE(none.ok());
  fs::remove_all(dir);
}

TEST(Submission, MetadataJsonIsStrict) {
  const std::string dir = temp_dir("meta");
  auto write = [&](const std::string& text) {
    std::ofstream(dir + "/m.json") << text;
    return read_submission_metadata(dir + "/m.json");
  };
  auto ok = write(R"({"account_name": "a@b.org", "authors": ["X"], "uses_lidar_data": false,
                      "acknowledge_complies_with_closed_loop_requirement": true, "num_model_parameters": "3M"})");
  ASSERT_TRUE(ok.ok()) << ok.status();
  EXPECT_EQ(ok->account_name, "a@b.org");
  EXPECT_TRUE(ok->acknowledge_complies_with_closed_loop_requirement);
  auto unknown = write(R"({"acount_name": "a@b.org"})");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("unknown key \"acount_name\""), std::string::npos);
  auto wrong = write(R"({"authors": "X"})");
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().message().find("\"authors\" must be a list of strings"), std::string::npos);
  EXPECT_FALSE(write("[1, 2]").ok());
  EXPECT_FALSE(write("{").ok());
  // What the challenge still needs is listed.
  const auto problems = challenge_problems({}, {}, *ok);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("unique_method_name, affiliation"), std::string::npos) << problems[0];
  fs::remove_all(dir);
}

// A model rollout as a complete WOMD scenario: the log up to the current frame, the rollout after it.
// A densify rollout (it creates agents) of the real test scenario, `steps` steps from its current one.
absl::StatusOr<std::vector<StepResult>> densify_rollout(const std::shared_ptr<const Scenario>& s, int steps) {
  auto model = Model::create(init_weights(*model_config_by_name("small"), 5));
  if (!model.ok()) return model.status();
  MapCache maps(*model);
  auto map = maps.get(*s);
  if (!map.ok()) return map.status();
  SessionOptions o;
  o.mode = SessionMode::densify;
  o.densify_target = 60;
  o.seed = 3;
  return run_model_rollout(*model, s, *map, o, SdcRule::model, steps);
}

TEST(RolloutExport, KeepsTheLogUpToTheCurrentFrame) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  auto steps = densify_rollout(s, 4);  // creates agents: their tracks must not collide with the log's
  ASSERT_TRUE(steps.ok()) << steps.status();
  auto out = rollout_to_scenario(*s, *steps);
  ASSERT_TRUE(out.ok()) << out.status();
  const int now = s->current_time_index;
  EXPECT_EQ(out->id, s->id);
  EXPECT_EQ(out->current_time_index, now);
  EXPECT_EQ(out->sdc_track_index, s->sdc_track_index);
  EXPECT_EQ(out->tracks_to_predict, s->tracks_to_predict);
  EXPECT_EQ(out->objects_of_interest, s->objects_of_interest);
  EXPECT_EQ(out->map_features, s->map_features);
  ASSERT_EQ(out->num_frames(), now + 1 + 4 * 5);
  for (int f = 0; f <= now; ++f) EXPECT_EQ(out->timestamps[f], s->timestamps[f]);
  for (int f = now + 1; f < out->num_frames(); ++f)
    EXPECT_NEAR(out->timestamps[f] - out->timestamps[f - 1], 0.1, 1e-9) << f;
  ASSERT_GE(out->tracks.size(), s->tracks.size());
  std::set<int32_t> ids;
  for (size_t i = 0; i < out->tracks.size(); ++i) {
    const Track& t = out->tracks[i];
    EXPECT_TRUE(ids.insert(t.id).second) << "id " << t.id << " twice";
    ASSERT_EQ(t.states.size(), static_cast<size_t>(out->num_frames()));
    if (i >= s->tracks.size()) {  // created by the model: no state up to the current frame
      for (int f = 0; f <= now; ++f) EXPECT_FALSE(t.states[f].valid);
      continue;
    }
    const Track& log = s->tracks[i];
    EXPECT_EQ(t.id, log.id);
    EXPECT_EQ(t.type, log.type);
    for (int f = 0; f <= now; ++f) EXPECT_EQ(t.states[f], log.states[f]) << t.id << " frame " << f;
    // z after the current frame: the last logged z.
    double z = NAN;
    for (int f = now; f >= 0 && std::isnan(z); --f)
      if (log.states[f].valid) z = log.states[f].z;
    for (int f = now + 1; f < out->num_frames(); ++f)
      if (t.states[f].valid) {
        EXPECT_EQ(t.states[f].z, z) << t.id << " frame " << f;
      }
  }
  EXPECT_GT(out->tracks.size(), s->tracks.size()) << "densify created no agent";
  // The SDC is driven by the model and stays valid over the rollout.
  const Track& sdc = out->tracks[s->sdc_track_index];
  for (int f = now; f < out->num_frames(); ++f) EXPECT_TRUE(sdc.states[f].valid) << f;
  // Signals: the log's up to the current frame, one entry per frame after it.
  ASSERT_EQ(out->signals.size(), static_cast<size_t>(out->num_frames()));
  for (int f = 0; f <= now; ++f) EXPECT_EQ(out->signals[f], s->signals[f]) << f;
  EXPECT_FALSE(out->signals[now + 1].empty());
  // Steps that do not start at the current frame are refused.
  std::vector<StepResult> late(steps->begin() + 1, steps->end());
  EXPECT_FALSE(rollout_to_scenario(*s, late).ok());
  EXPECT_FALSE(rollout_to_scenario(*s, {}).ok());
}

TEST(RolloutExport, AgentGoneAfterTheCurrentStepGetsNoTrack) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  auto steps = densify_rollout(s, 2);
  ASSERT_TRUE(steps.ok()) << steps.status();
  // A generated agent (an id the log does not use) that retires right after the current step: its only state is
  // at the current frame, which is the log's, so it has nothing to show.
  std::set<int64_t> log_ids;
  for (const Track& t : s->tracks) log_ids.insert(t.id);
  int64_t gone = -1;
  for (const AgentView& a : steps->front().agents)
    if (!log_ids.count(a.id)) gone = a.id;
  ASSERT_GE(gone, 0) << "densify created no agent at the current step";
  for (size_t k = 1; k < steps->size(); ++k)
    std::erase_if((*steps)[k].agents, [&](const AgentView& a) { return a.id == gone; });
  auto out = rollout_to_scenario(*s, *steps);
  ASSERT_TRUE(out.ok()) << out.status();
  for (size_t i = 0; i < out->tracks.size(); ++i) {
    const Track& t = out->tracks[i];
    EXPECT_NE(t.id, gone);
    if (i >= s->tracks.size()) {  // generated (a log track keeps its frames, valid or not)
      EXPECT_TRUE(std::any_of(t.states.begin(), t.states.end(), [](const ObjectState& x) { return x.valid; })) << t.id;
    }
  }
}

}  // namespace
}  // namespace ss
