// The Scenario Generation Challenge's metric on vectors worked out by hand (histograms pooled over objects, the
// traffic-light term per object), the agent counts, the placement baseline and the log oracle, and the submission
// files' round trip (written, read back, scored: the same numbers).
#include "offline/eval/scenario_gen.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <unistd.h>

#include "offline/eval/submission.h"
#include "engine/scenario/read.h"
#include "engine/tokens/fidelity.h"

namespace ss {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Two objects over five frames, every one valid in the log: object 0 a vehicle, object 1 a pedestrian. Every
// feature 0 unless set.
SceneFeatures blank() {
  SceneFeatures f;
  for (auto& v : f.values) v.assign(2, std::vector<double>(5, 0.0));
  f.valid.assign(2, std::vector<uint8_t>(5, 1));
  return f;
}

TEST(ScenarioGenMetric, HandWorkedVectors) {
  SceneFeatures log = blank();
  std::vector<SceneFeatures> sims(2, blank());
  // Linear speed (0..25 m/s, 10 bins of 2.5, pseudo-count 0.1). Rollout 0: object 0 at 1 m/s (bin 0), object 1 at
  // 6 m/s (bin 2); rollout 1 the same but object 0's last frame NaN (the last bin, 9) and object 1's first 26 m/s
  // (clipped to 25: bin 9). Pooled over objects, rollouts and frames: bin 0 holds 9, bin 2 holds 9, bin 9 holds 2,
  // N = 20, so P(bin 0) = P(bin 2) = (9 + 0.1) / (20 + 10 x 0.1) = 9.1 / 21.
  sims[0].values[kLinearSpeed] = {{1, 1, 1, 1, 1}, {6, 6, 6, 6, 6}};
  sims[1].values[kLinearSpeed] = {{1, 1, 1, 1, kNaN}, {26, 6, 6, 6, 6}};
  // The log's speeds are scored where both neighbours are valid, frames 1-3: object 0 at 6 m/s, object 1 at 1 m/s.
  // Per object (sim agents) each would be scored against its own rollouts, bins it never reached: 0.1 / 5.1.
  log.values[kLinearSpeed] = {{kNaN, 6, 6, 6, kNaN}, {kNaN, 1, 1, 1, kNaN}};
  // Time to collision (0..5 s, 10 bins of 0.5): object 0 always 5 s (bin 9), the pedestrian 0.2 s (bin 0) in both
  // rollouts: pooled 10 and 10 of N = 20. The log is scored on the vehicle only (5 frames): 5, 0.2, 5, 5, 4.9 s, all
  // in bins 0 or 9: each (10 + 0.1) / 21.
  for (auto& s : sims) s.values[kTimeToCollision] = {{5, 5, 5, 5, 5}, {0.2, 0.2, 0.2, 0.2, 0.2}};
  log.values[kTimeToCollision] = {{5, 0.2, 5, 5, 4.9}, {4, 4, 4, 4, 4}};
  // Collision (Bernoulli, pseudo-count 0.001): the log's object 0 collides (frame 4), object 1 does not; of the
  // rollouts' four (rollout, object) indications one is a collision (rollout 0, object 1). Pooled:
  // P(1) = 1.001 / 4.002, P(0) = 3.001 / 4.002; the mean over the log's two objects of log P.
  log.values[kCollision][0][4] = 1;
  sims[0].values[kCollision][1][0] = 1;
  // Traffic-light violation: not pooled, vehicles only. Object 0 runs a light in the log and in rollout 0:
  // P = 1.001 / 2.002; the pedestrian's violation in rollout 1 is masked out: P(0) = 2.001 / 2.002.
  log.values[kTrafficLightViolation][0][1] = 1;
  sims[0].values[kTrafficLightViolation][0][2] = 1;
  sims[1].values[kTrafficLightViolation][1][1] = 1;
  const std::vector<ObjectType> types = {ObjectType::vehicle, ObjectType::pedestrian};

  const RealismScores r = score_scenario_gen(log, sims, types);
  EXPECT_NEAR(r.likelihood[kLinearSpeed], 9.1 / 21, 1e-12);
  EXPECT_NEAR(r.likelihood[kTimeToCollision], 10.1 / 21, 1e-12);
  EXPECT_NEAR(r.likelihood[kCollision], std::sqrt(1.001 * 3.001) / 4.002, 1e-12);
  EXPECT_NEAR(r.likelihood[kTrafficLightViolation], std::sqrt(1.001 * 2.001) / 2.002, 1e-12);
  // Every other feature is 0 everywhere: all 20 pooled values in one bin, (20 + 0.1) / (20 + B x 0.1); the
  // accelerations are scored at frame 2 only, the distances at every frame; nobody goes off road: 4.001 / 4.002.
  EXPECT_NEAR(r.likelihood[kLinearAcceleration], 20.1 / 21.1, 1e-12);
  EXPECT_NEAR(r.likelihood[kAngularSpeed], 20.1 / 21.1, 1e-12);
  EXPECT_NEAR(r.likelihood[kAngularAcceleration], 20.1 / 21.1, 1e-12);
  EXPECT_NEAR(r.likelihood[kDistanceToNearestObject], 20.1 / 21, 1e-12);
  EXPECT_NEAR(r.likelihood[kDistanceToRoadEdge], 20.1 / 21, 1e-12);
  EXPECT_NEAR(r.likelihood[kOffroad], 4.001 / 4.002, 1e-12);
  // The meta-metric: the 2025 weights.
  const double meta = 0.05 * (9.1 / 21) + 0.05 * 3 * (20.1 / 21.1) + 0.10 * (20.1 / 21) +
                      0.25 * std::sqrt(1.001 * 3.001) / 4.002 + 0.10 * (10.1 / 21) + 0.05 * (20.1 / 21) +
                      0.25 * (4.001 / 4.002) + 0.05 * std::sqrt(1.001 * 2.001) / 2.002;
  EXPECT_NEAR(r.meta, meta, 1e-12);
  EXPECT_NEAR(r.collision_rate, 0.25, 1e-12);
  EXPECT_EQ(r.offroad_rate, 0.0);
  EXPECT_TRUE(std::isnan(r.min_ade));  // no generated agent stands for a logged one

  // The config: every feature pooled but the light violations.
  for (int f = 0; f < kNumRealismFeatures; ++f)
    EXPECT_EQ(scenario_gen_aggregated(static_cast<RealismFeature>(f)), f != kTrafficLightViolation);
}

TEST(ScenarioGenMetric, PoolingIgnoresWhichGeneratedAgentWearsWhichId) {
  // Swapping two objects' simulated values changes nothing pooled (the indications' masks are the same here).
  SceneFeatures log = blank();
  std::vector<SceneFeatures> sims(3, blank());
  for (int k = 0; k < 3; ++k) sims[k].values[kLinearSpeed] = {{1.0 + k, 2, 3, 4, 5}, {10, 11, 12.0 - k, 13, 14}};
  log.values[kLinearSpeed] = {{0, 3, 4, 12, 0}, {0, 1, 11, 2, 0}};
  const std::vector<ObjectType> types = {ObjectType::vehicle, ObjectType::vehicle};
  const RealismScores a = score_scenario_gen(log, sims, types);
  for (auto& s : sims) std::swap(s.values[kLinearSpeed][0], s.values[kLinearSpeed][1]);
  const RealismScores b = score_scenario_gen(log, sims, types);
  EXPECT_DOUBLE_EQ(a.likelihood[kLinearSpeed], b.likelihood[kLinearSpeed]);
}

TEST(ScenarioGenScenes, ClearHistoryHoldsAnAgentWhereItsStepBackWouldOverlap) {
  // Frame 3 is the current one. A (settled, e.g. the SDC's log) stands at x = 0; B, 7 m ahead and moving at 20 m/s,
  // would pass through it going back (x = 5, 3, 1 at frames 2, 1, 0; 4 m boxes); C, far off, moves freely.
  auto object = [](std::vector<double> xs, double y) {
    SceneObject o;
    for (double x : xs) o.states.push_back({x, y, 0, 0, 4.0, 2.0, 1.5, true});
    return o;
  };
  JointScene scene;
  scene.objects = {object({0, 0, 0, 0}, 0), object({1, 3, 5, 7}, 0), object({-30, -20, -10, 0}, 50)};
  clear_history(scene, 3, {1, 2});
  // Frame 2 (x = 5) is clear of A; frame 1 (x = 3) would overlap it, so B stood at x = 5 from there back.
  EXPECT_EQ(scene.objects[1].states[2].x, 5.0);
  EXPECT_EQ(scene.objects[1].states[1].x, 5.0);
  EXPECT_EQ(scene.objects[1].states[0].x, 5.0);
  EXPECT_EQ(scene.objects[2].states[0].x, -30.0);  // C untouched
  EXPECT_EQ(scene.objects[0].states[0].x, 0.0);    // the settled object too
}

TEST(ScenarioGenScenes, ClearHistoryDoesNotDependOnTheOrderOfTheMovedAgents) {
  // Two generated agents, no settled one: P stands at x = 0 throughout; Q, at x = 5 now (frame 3), moved off from
  // where P stands (x = 0 at frame 2). Going back, Q's step into P's place makes Q hold at x = 5, whichever of the
  // two is decided first (deciding them one by one, Q first, left P inside Q: P's step back and its hold both met
  // Q's box, already settled there).
  auto object = [](std::vector<double> xs) {
    SceneObject o;
    for (double x : xs) o.states.push_back({x, 0, 0, 0, 4.0, 2.0, 1.5, true});
    return o;
  };
  for (const std::vector<size_t>& order : {std::vector<size_t>{0, 1}, std::vector<size_t>{1, 0}}) {
    JointScene scene;
    scene.objects = {object({0, 0, 0, 0}), object({-10, -5, 0, 5})};
    clear_history(scene, 3, order);
    for (int f = 0; f < 3; ++f) {
      EXPECT_EQ(scene.objects[0].states[f].x, 0.0) << "order " << order[0] << ", frame " << f;
      EXPECT_EQ(scene.objects[1].states[f].x, 5.0) << "order " << order[0] << ", frame " << f;
    }
  }
}

TEST(ScenarioGenCounts, ParsedAndRefusedByName) {
  auto c = parse_agent_counts("12,3,0");
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(*c, (std::array<int, 3>{12, 3, 0}));
  for (const char* bad : {"1,2", "1,2,3,4", "a,1,1", "1,-2,1", "1,1,2000"}) {
    auto b = parse_agent_counts(bad);
    EXPECT_FALSE(b.ok()) << bad;
  }
  EXPECT_NE(std::string(parse_agent_counts("1,x,1").status().message()).find("'x'"), std::string::npos);
}

std::shared_ptr<const Scenario> load(const std::string& path) {
  auto s = read_scenarios(std::string(SS_DATA_DIR) + path);
  EXPECT_TRUE(s.ok()) << s.status();
  return std::make_shared<const Scenario>((*s)[0]);
}

constexpr const char* kScenario = "/womd/tfrecord/motion_data_one_scenario.tfrecord";

TEST(ScenarioGenScenes, CountsAreTheLogsSimAgentsButTheSdc) {
  const auto s = load(kScenario);
  const std::array<int, 3> c = scenario_gen_counts(*s);
  std::array<int, 3> expected{};
  int sdc = 0;
  for (int t : sim_agent_tracks(*s)) {
    if (t == s->sdc_track_index) ++sdc;
    else ++expected[model_type(s->tracks[t].type)];
  }
  EXPECT_EQ(sdc, 1);
  EXPECT_EQ(c, expected);
  EXPECT_GT(c[0], 0);
  EXPECT_EQ(scenario_gen_problem(*s), "");
}

TEST(ScenarioGenScenes, PlacementBaselinePlacesTheCountsClearOfEachOther) {
  const auto s = load(kScenario);
  const int now = s->current_time_index;
  for (uint64_t seed : {1, 2}) {
    const GeneratedScene g = placement_scene(*s, 100.0, seed);
    EXPECT_EQ(g.placed, scenario_gen_counts(*s));
    EXPECT_EQ(g.overlapping_pairs, 0);
    ASSERT_EQ(g.scene.objects.size(), sim_agent_tracks(*s).size());
    for (const SceneObject& o : g.scene.objects) {
      ASSERT_EQ(o.states.size(), static_cast<size_t>(s->num_frames()));
      for (const BoxState& b : o.states) EXPECT_TRUE(b.valid);
    }
    // Constant velocity: the same displacement every frame.
    const SceneObject& o = g.scene.objects[0];
    const double dx = o.states[now + 1].x - o.states[now].x;
    EXPECT_NEAR(o.states[1].x - o.states[0].x, dx, 1e-9);
  }
}

TEST(ScenarioGenScenes, TheLogOracleScoresAboveThePlacementBaseline) {
  const auto s = load(kScenario);
  ScenarioGenOptions o;
  o.rollouts = 2;
  o.policy = ScenarioGenPolicy::log_oracle;
  auto log = evaluate_scenario_gen(s, o, nullptr, nullptr);
  ASSERT_TRUE(log.ok()) << log.status();
  o.policy = ScenarioGenPolicy::placement;
  auto placed = evaluate_scenario_gen(s, o, nullptr, nullptr);
  ASSERT_TRUE(placed.ok()) << placed.status();
  EXPECT_GT(log->realism.meta, placed->realism.meta);
  EXPECT_EQ(log->exact_rollouts, 2);
  EXPECT_EQ(placed->exact_rollouts, 2);
  // The log's initial states against themselves: no discrepancy.
  EXPECT_NEAR(log->mmd_relaxed.position, 0.0, 1e-12);
}

std::string temp_dir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("ss_scenario_gen_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

TEST(ScenarioGenSubmission, WrittenReadBackAndScoredGivesTheSameNumbers) {
  const auto s = load(kScenario);
  ScenarioGenOptions o;
  o.rollouts = 3;
  o.policy = ScenarioGenPolicy::placement;
  o.submission_precision = true;
  std::vector<JointScene> scenes;
  auto direct = evaluate_scenario_gen(s, o, nullptr, nullptr, nullptr, &scenes);
  ASSERT_TRUE(direct.ok()) << direct.status();
  auto rollouts = scenegen_rollouts_from_scenes(*s, scenes);
  ASSERT_TRUE(rollouts.ok()) << rollouts.status();
  ASSERT_EQ(rollouts->joint_scenes[0][0].x.size(), static_cast<size_t>(s->num_frames()));  // every frame
  const std::string dir = temp_dir("round_trip");
  ASSERT_TRUE(write_submission(dir, {*rollouts}, {}).ok());
  auto read = read_submission({dir});
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->rollouts.size(), 1u);
  const SimulatedTrajectory& t = read->rollouts[0].joint_scenes[0][0];
  EXPECT_EQ(t.object_type, static_cast<int32_t>(scenes[0].objects[0].type));
  EXPECT_EQ(t.length.size(), static_cast<size_t>(s->num_frames()));
  auto back = scenegen_scenes_from_rollouts(*s, read->rollouts[0], dir);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), scenes.size());
  for (size_t r = 0; r < scenes.size(); ++r)
    for (size_t k = 0; k < scenes[r].objects.size(); ++k)
      for (size_t f = 0; f < scenes[r].objects[k].states.size(); ++f) {
        const BoxState& a = scenes[r].objects[k].states[f];
        const BoxState& b = (*back)[r].objects[k].states[f];
        ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z && a.heading == b.heading && a.length == b.length &&
                    a.width == b.width && a.height == b.height && b.valid)
            << "rollout " << r << " object " << k << " frame " << f;
      }
  ScenarioGenOptions from_file;
  from_file.policy = ScenarioGenPolicy::submission;
  auto scored = evaluate_scenario_gen(s, from_file, nullptr, nullptr, &*back);
  ASSERT_TRUE(scored.ok()) << scored.status();
  for (int f = 0; f < kNumRealismFeatures; ++f)
    EXPECT_EQ(scored->realism.likelihood[f], direct->realism.likelihood[f]) << wosac_2025_config()[f].name;
  EXPECT_EQ(scored->realism.meta, direct->realism.meta);
  EXPECT_EQ(scored->exact_rollouts, 3);
  fs::remove_all(dir);
}

TEST(ScenarioGenSubmission, MalformedTrajectoriesAreRefusedByName) {
  const auto s = load(kScenario);
  auto rollouts = scenegen_rollouts_from_scenes(*s, {placement_scene(*s, 100.0, 1).scene});
  ASSERT_TRUE(rollouts.ok());
  auto refused = [&](auto change, const std::string& words) {
    ScenarioRollouts r = *rollouts;
    change(r.joint_scenes[0]);
    auto got = scenegen_scenes_from_rollouts(*s, r, "sub");
    ASSERT_FALSE(got.ok()) << words;
    EXPECT_NE(std::string(got.status().message()).find(words), std::string::npos) << got.status();
  };
  const std::string id = std::to_string(rollouts->joint_scenes[0][0].object_id);
  refused([](auto& j) { j[0].length.pop_back(); }, "length values");
  refused([](auto& j) { j[0].object_type = 4; }, "object_type 4");
  refused([](auto& j) { j[0].height[3] = NAN; }, "non-finite");
  refused([](auto& j) { j.push_back(j[0]); }, "given twice");
  refused([](auto& j) { j.erase(j.begin()); }, "sim agent " + id + " (valid at the current frame) is missing");
}

}  // namespace
}  // namespace ss
