// The policies on real WOMD scenarios (read in place from ../shared): log replay must score higher realism than
// constant velocity; the model's rollouts become 10 Hz scenes aligned with the log, reproducibly per seed.
#include <gtest/gtest.h>

#include <cmath>

#include "offline/eval/aggregate.h"
#include "offline/eval/baselines.h"
#include "offline/eval/evaluate.h"
#include "offline/eval/model_rollout.h"
#include "engine/model/weights.h"
#include "engine/scenario/read.h"

namespace ss {
namespace {

std::shared_ptr<const Scenario> load(const std::string& path) {
  auto s = read_scenarios(std::string(SS_DATA_DIR) + path);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::make_shared<const Scenario>((*s)[0]);
}

ScenarioEvaluation run(std::shared_ptr<const Scenario> s, EvalPolicy policy, int k = 2) {
  EvalOptions o;
  o.policy = policy;
  o.rollouts = k;
  auto r = evaluate_scenario(s, o, nullptr, nullptr);
  EXPECT_TRUE(r.ok()) << r.status();
  return *r;
}

TEST(Policies, LogReplayScoresAboveConstantVelocity) {
  // A WOMD TFRecord (SDC + tracks_to_predict), a newer JSON file with metadata and lights, an older one without.
  for (const char* path : {"/womd/tfrecord/motion_data_one_scenario.tfrecord", "/womd/json/val/womd_27d205cc.json",
                           "/womd/json/val/womd_d5b57279.json"}) {
    SCOPED_TRACE(path);
    const auto s = load(path);
    const ScenarioEvaluation log = run(s, EvalPolicy::log_replay);
    const ScenarioEvaluation cv = run(s, EvalPolicy::constant_velocity);
    EXPECT_GT(log.realism.meta, cv.realism.meta);
    EXPECT_DOUBLE_EQ(log.realism.min_ade, 0.0);
    EXPECT_DOUBLE_EQ(log.motion_all.ade_avg, 0.0);
    EXPECT_DOUBLE_EQ(log.motion_all.add, 0.0);  // identical rollouts
    EXPECT_GT(cv.realism.min_ade, 0.0);
    EXPECT_GE(cv.motion_all.fde_avg, cv.motion_all.ade_avg);  // errors grow with time
  }
}

TEST(Policies, EvaluatedObjects) {
  const auto womd = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  const EvaluatedObjects e = evaluated_objects(*womd);
  EXPECT_TRUE(e.named_by_scenario);
  EXPECT_EQ(e.tracks.size(), 4u);  // the SDC and 3 tracks to predict
  for (size_t i = 1; i < e.tracks.size(); ++i) EXPECT_LT(womd->tracks[e.tracks[i - 1]].id, womd->tracks[e.tracks[i]].id);
  const auto old = load("/womd/json/val/womd_d5b57279.json");
  const EvaluatedObjects all = evaluated_objects(*old);
  EXPECT_FALSE(all.named_by_scenario);
  EXPECT_EQ(all.tracks.size(), sim_agent_tracks(*old).size());
}

TEST(Policies, ConstantVelocityScene) {
  const auto s = load("/womd/json/val/womd_d5b57279.json");
  const std::vector<int> tracks = sim_agent_tracks(*s);
  const JointScene cv = constant_velocity_scene(*s, tracks);
  const int now = s->current_time_index;
  for (size_t k = 0; k < tracks.size(); ++k) {
    const ObjectState& o = s->tracks[tracks[k]].states[now];
    const BoxState& end = cv.objects[k].states[90];
    EXPECT_TRUE(end.valid);
    EXPECT_NEAR(end.x, o.x + o.vx * 8.0, 1e-6);
    EXPECT_NEAR(end.y, o.y + o.vy * 8.0, 1e-6);
    EXPECT_NEAR(end.heading, o.heading, 1e-6);
    EXPECT_NEAR(end.length, o.length, 1e-6);
    EXPECT_EQ(cv.objects[k].states[3].valid, s->tracks[tracks[k]].states[3].valid);  // history is the log
  }
}

TEST(Policies, ModelRolloutsAreAlignedAndReproducible) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");
  auto model = Model::create(init_weights(*model_config_by_name("small"), 5));
  ASSERT_TRUE(model.ok()) << model.status();
  MapCache maps(*model);
  EvalOptions o;
  o.policy = EvalPolicy::model;
  o.rollouts = 2;
  o.session.mode = SessionMode::motion;
  o.session.seed = 9;
  auto a = evaluate_scenario(s, o, *model, &maps);
  ASSERT_TRUE(a.ok()) << a.status();
  auto b = evaluate_scenario(s, o, *model, &maps);
  ASSERT_TRUE(b.ok()) << b.status();
  EXPECT_EQ(a->realism.meta, b->realism.meta);  // seeded per scenario and rollout
  EXPECT_EQ(a->motion_all.ade_avg, b->motion_all.ade_avg);
  EXPECT_GT(a->realism.meta, 0.0);
  EXPECT_LT(a->filled_share, 0.5);  // the model drives most sim agents
  EXPECT_FALSE(a->has_mmd);

  // The scene: history is the log; under SdcRule::log the SDC replays its log at every 2 Hz step.
  SessionOptions so;
  so.seed = 3;
  auto map = maps.get(*s);
  ASSERT_TRUE(map.ok());
  auto steps = run_model_rollout(*model, s, *map, so, SdcRule::log);
  ASSERT_TRUE(steps.ok()) << steps.status();
  EXPECT_EQ(steps->size(), 17u);
  const std::vector<int> tracks = sim_agent_tracks(*s);
  const RolloutScene r = rollout_scene(*s, tracks, *steps, false);
  ASSERT_EQ(r.scene.num_frames(), 91);
  const int sdc = scene_indices(tracks, {s->sdc_track_index})[0];
  for (int f = 0; f <= 90; f += 5) {
    const ObjectState& log = s->tracks[s->sdc_track_index].states[f];
    EXPECT_NEAR(r.scene.objects[sdc].states[f].x, log.x, 1e-3) << f;
    EXPECT_NEAR(r.scene.objects[sdc].states[f].y, log.y, 1e-3) << f;
  }
  for (const SceneObject& o : r.scene.objects)
    for (int f = 11; f <= 90; ++f) EXPECT_TRUE(o.states[f].valid);

  // Full mode: the model generates the scene; its agents stand in for the log's and the MMD is measured.
  o.session.mode = SessionMode::full;
  o.rollouts = 1;
  auto full = evaluate_scenario(s, o, *model, &maps);
  ASSERT_TRUE(full.ok()) << full.status();
  EXPECT_TRUE(full->has_mmd);
  // Random weights may generate no agent at all (then the MMD is undefined); a defined MMD is never negative.
  for (double v : {full->mmd_relaxed.position, full->mmd_relaxed.heading, full->mmd_strict.size})
    EXPECT_TRUE(std::isnan(v) || v >= 0.0);
  EXPECT_LE(full->matched, full->to_match);
  const std::vector<ScenarioEvaluation> both = {*a, *full};
  const DatasetEvaluation d = aggregate(both);
  EXPECT_EQ(d.scenarios, 2);
  EXPECT_NEAR(d.realism.meta, (a->realism.meta + full->realism.meta) / 2, 1e-12);
}

}  // namespace
}  // namespace ss
