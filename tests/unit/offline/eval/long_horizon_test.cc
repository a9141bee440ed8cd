// Long horizons: scenarios of any length are rolled out to their end and scored per window (0-8 s, 8-16 s, 16 s to
// the end), on hand-built features and on a real 20 s WOMD scenario (read in place from ../shared).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <set>

#include "offline/eval/aggregate.h"
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

// The frame count of every file json-20s/README.md's table lists ("| womd20s_x.json | 199 | ..."): the reference for
// what the folder holds, so that the data can grow with only its README changing.
std::map<std::string, int> readme_frames() {
  std::ifstream in(std::string(SS_DATA_DIR) + "/womd/json-20s/README.md");
  std::map<std::string, int> out;
  std::string line;
  const std::regex row(R"(^\|\s*(\S+\.json)\s*\|\s*(\d+)\s*\|)");
  for (std::smatch m; std::getline(in, line);)
    if (std::regex_search(line, m, row)) out[m[1]] = std::stoi(m[2]);
  return out;
}

TEST(LongHorizon, ReadersTakeAnyNumberOfFrames) {
  // The real 20 s scenarios, each with the frames its README says, and a TFRecord written from them read back with
  // the same frames.
  const std::map<std::string, int> listed = readme_frames();
  ASSERT_GE(listed.size(), 4u) << "json-20s/README.md lists no files (its table's layout changed?)";
  auto all = read_scenarios(std::string(SS_DATA_DIR) + "/womd/json-20s");
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_EQ(all->size(), listed.size());
  std::multiset<int> frames, expected;
  for (const auto& [file, n] : listed) expected.insert(n);
  for (const Scenario& s : *all) {
    frames.insert(s.num_frames());
    EXPECT_EQ(s.current_time_index, 10);
    EXPECT_GE(s.num_frames(), 191) << s.id << ": not a 20 s scenario";
  }
  EXPECT_EQ(frames, expected);
  const std::string path = ::testing::TempDir() + "/long_horizon.tfrecord";
  ASSERT_TRUE(write_scenarios_tfrecord(path, *all).ok());
  auto back = read_scenarios(path);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), all->size());
  for (size_t i = 0; i < all->size(); ++i) EXPECT_EQ((*back)[i].num_frames(), (*all)[i].num_frames());
  std::remove(path.c_str());
}

TEST(LongHorizon, Windows) {
  auto spans = [](int future) {
    std::vector<std::pair<int, int>> out;
    for (const FrameWindow& w : realism_windows(future)) out.push_back({w.begin, w.end});
    return out;
  };
  using V = std::vector<std::pair<int, int>>;
  EXPECT_EQ(spans(80), (V{{0, 80}}));  // WOMD's 91 frames: one window, the whole future
  EXPECT_EQ(spans(50), (V{{0, 50}}));
  EXPECT_EQ(spans(81), (V{{0, 80}, {80, 81}}));
  EXPECT_EQ(spans(188), (V{{0, 80}, {80, 160}, {160, 188}}));  // a 199-frame scenario
  EXPECT_EQ(spans(400), (V{{0, 80}, {80, 160}, {160, 400}}));  // the last window runs to the end
  EXPECT_TRUE(spans(0).empty());
  EXPECT_STREQ(realism_window_name(2), "16 s-end");
}

// One object over 6 simulated frames; every feature 0 unless set.
SceneFeatures features() {
  SceneFeatures f;
  for (auto& v : f.values) v = {std::vector<double>(6, 0.0)};
  f.valid = {std::vector<uint8_t>(6, 1)};
  f.ade = {0.0};
  f.displacement = {std::vector<double>(6, 0.0)};
  return f;
}

TEST(LongHorizon, WindowScoresOnlyItsFrames) {
  const SceneFeatures log = features();
  SceneFeatures hit = features(), clear = features();
  hit.values[kCollision][0][4] = 1;  // one rollout collides at frame 4, in the second window only
  hit.displacement[0] = {0, 0, 0, 2, 4, 6};
  clear.displacement[0] = {0, 0, 0, 1, 1, 1};
  hit.ade = {1.5}, clear.ade = {0.25};  // whole-future ADE (WOSAC's: history included) as given
  const std::vector<SceneFeatures> sims = {hit, clear};
  const std::vector<ObjectType> types = {ObjectType::vehicle};
  const RealismScores first = score_realism(log, sims, types, {0, 3});
  const RealismScores second = score_realism(log, sims, types, {3, 6});
  const RealismScores whole = score_realism(log, sims, types);
  // Bernoulli with 2 rollouts, a = 0.001: no rollout collides in the first window, one of two in the second.
  EXPECT_NEAR(first.likelihood[kCollision], 2.001 / 2.002, 1e-12);
  EXPECT_NEAR(second.likelihood[kCollision], 1.001 / 2.002, 1e-12);
  EXPECT_NEAR(whole.likelihood[kCollision], 1.001 / 2.002, 1e-12);
  EXPECT_DOUBLE_EQ(first.collision_rate, 0.0);
  EXPECT_DOUBLE_EQ(second.collision_rate, 0.5);
  // A window's ADE averages its own frames; the whole future keeps WOSAC's ADE.
  EXPECT_DOUBLE_EQ(first.min_ade, 0.0);
  EXPECT_DOUBLE_EQ(second.min_ade, 1.0);    // min(4, 1)
  EXPECT_DOUBLE_EQ(second.ade, 2.5);        // mean(4, 1)
  EXPECT_DOUBLE_EQ(whole.min_ade, 0.25);
  // A window covering the whole future is the whole.
  const RealismScores all = score_realism(log, sims, types, {0, 6});
  EXPECT_EQ(all.meta, whole.meta);
  EXPECT_EQ(all.min_ade, whole.min_ade);
}

TEST(LongHorizon, WindowLeavesOutObjectsTheLogLacksThere) {
  // Two objects; the log loses the second after frame 2; the one rollout's first object collides at frame 4. In the
  // second window only the first object is scored: the second, which cannot collide where the log has no frame,
  // would otherwise halve the collision rate and lift the likelihood.
  SceneFeatures log = features();
  for (auto& v : log.values) v.push_back(std::vector<double>(6, 0.0));
  log.valid.push_back({1, 1, 1, 0, 0, 0});
  SceneFeatures sim = log;
  sim.ade = {0.0, 0.0};
  sim.displacement = {std::vector<double>(6, 0.0), std::vector<double>(6, 0.0)};
  sim.values[kCollision][0][4] = 1;
  const std::vector<SceneFeatures> sims = {sim};
  const std::vector<ObjectType> types = {ObjectType::vehicle, ObjectType::vehicle};
  const RealismScores second = score_realism(log, sims, types, {3, 6});
  EXPECT_NEAR(second.likelihood[kCollision], 0.001 / 1.002, 1e-12);  // the first object only
  EXPECT_DOUBLE_EQ(second.collision_rate, 1.0);
  EXPECT_EQ(second.objects, 1);
  // Over the whole future both objects count, as in WOSAC.
  const RealismScores whole = score_realism(log, sims, types);
  EXPECT_NEAR(whole.likelihood[kCollision], std::sqrt(0.001 / 1.002 * 1.001 / 1.002), 1e-12);
  EXPECT_DOUBLE_EQ(whole.collision_rate, 0.5);
  EXPECT_EQ(whole.objects, 2);
}

TEST(LongHorizon, RealTwentySecondScenarioRolledOutToItsEnd) {
  // 198 frames (the reader takes any number), current frame 10: 187 simulated frames in three windows.
  const auto s = load("/womd/json-20s/womd20s_92ddde4b.json");
  ASSERT_EQ(s->num_frames(), 198);
  ASSERT_EQ(s->current_time_index, 10);
  EvalOptions o;
  o.rollouts = 2;
  o.policy = EvalPolicy::log_replay;
  auto replay = evaluate_scenario(s, o, nullptr, nullptr);
  ASSERT_TRUE(replay.ok()) << replay.status();
  o.policy = EvalPolicy::constant_velocity;
  auto cv = evaluate_scenario(s, o, nullptr, nullptr);
  ASSERT_TRUE(cv.ok()) << cv.status();
  EXPECT_EQ(cv->future_frames, 187);
  ASSERT_EQ(cv->windows.size(), 3u);
  ASSERT_EQ(replay->windows.size(), 3u);
  for (size_t w = 0; w < 3; ++w) {
    SCOPED_TRACE(w);
    EXPECT_DOUBLE_EQ(replay->windows[w].min_ade, 0.0);
    EXPECT_GT(replay->windows[w].meta, cv->windows[w].meta);
    EXPECT_GT(cv->windows[w].min_ade, 0.0);
  }
  // Constant velocity drifts: its error grows from window to window.
  EXPECT_LT(cv->windows[0].min_ade, cv->windows[1].min_ade);
  EXPECT_LT(cv->windows[1].min_ade, cv->windows[2].min_ade);

  // A 91-frame scenario has one window, equal to the whole; the dataset counts each window's scenarios.
  const auto short_one = load("/womd/json/val/womd_d5b57279.json");
  auto cv91 = evaluate_scenario(short_one, o, nullptr, nullptr);
  ASSERT_TRUE(cv91.ok()) << cv91.status();
  ASSERT_EQ(cv91->windows.size(), 1u);
  EXPECT_EQ(cv91->windows[0].meta, cv91->realism.meta);
  EXPECT_EQ(cv91->windows[0].min_ade, cv91->realism.min_ade);
  const std::vector<ScenarioEvaluation> both = {*cv, *cv91};
  const DatasetEvaluation d = aggregate(both);
  ASSERT_EQ(d.windows.size(), 3u);
  EXPECT_EQ(d.windows[0].scenarios, 2);
  EXPECT_EQ(d.windows[1].scenarios, 1);
  EXPECT_NEAR(d.windows[0].realism.meta, (cv->windows[0].meta + cv91->windows[0].meta) / 2, 1e-12);
  EXPECT_DOUBLE_EQ(d.windows[2].realism.meta, cv->windows[2].meta);
  EXPECT_TRUE(d.undefined.empty());  // a scenario too short for a window is not "undefined" there
}

TEST(LongHorizon, ModelDrivesTheSdcForTwentySeconds) {
  // The random small model, the SDC driven by the model (no controlled agent): the region of interest follows the
  // SDC, so it stays in the session however far it drives, and the rollout covers every frame to the end.
  const auto s = load("/womd/json-20s/womd20s_92ddde4b.json");
  auto model = Model::create(init_weights(*model_config_by_name("small"), 5));
  ASSERT_TRUE(model.ok()) << model.status();
  MapCache maps(*model);
  auto map = maps.get(*s);
  ASSERT_TRUE(map.ok()) << map.status();
  SessionOptions o;
  o.seed = 2;
  o.roi_radius = 2;  // tiny: a region left where the SDC started would retire it as soon as it moved 2 m
  auto steps = run_model_rollout(*model, s, *map, o, SdcRule::model);
  ASSERT_TRUE(steps.ok()) << steps.status();
  ASSERT_EQ(steps->size(), 1u + 38u);  // ceil(187 / 5) steps after the current one
  EXPECT_GE(steps->back().step * kFramesPerStep, s->num_frames() - 1);
  const int64_t sdc_id = s->tracks[s->sdc_track_index].id;
  const ObjectState& start = s->tracks[s->sdc_track_index].states[s->current_time_index];
  double farthest = 0;
  for (const StepResult& step : *steps) {
    const AgentView* sdc = nullptr;
    for (const AgentView& a : step.agents)
      if (a.id == sdc_id) sdc = &a;
    ASSERT_NE(sdc, nullptr) << "the SDC left the session at step " << step.step;
    EXPECT_FALSE(sdc->controlled);
    farthest = std::max(farthest, std::hypot(sdc->state.x - start.x, sdc->state.y - start.y));
  }
  EXPECT_GT(farthest, 2 * o.roi_radius);  // it did drive out of where the region started
  const std::vector<int> tracks = sim_agent_tracks(*s);
  const RolloutScene r = rollout_scene(*s, tracks, *steps, false);
  ASSERT_EQ(r.scene.num_frames(), 198);
  const int k = scene_indices(tracks, {s->sdc_track_index})[0];
  for (int f = 11; f < 198; ++f) EXPECT_TRUE(r.scene.objects[k].states[f].valid) << f;
}

}  // namespace
}  // namespace ss
