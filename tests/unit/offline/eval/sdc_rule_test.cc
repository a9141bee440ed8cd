// Who drives the SDC (eval --sdc): under SdcRule::model no logged pose after the current frame reaches a rollout's
// session, and the SDC is scored; under SdcRule::log the SDC replays its log and is not among the evaluated objects.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

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

std::shared_ptr<const Model> small_model() {
  auto model = Model::create(init_weights(*model_config_by_name("small"), 5));
  EXPECT_TRUE(model.ok()) << model.status();
  return *model;
}

// The same scenario with every logged pose after the current frame moved (by 3 m: a controlled agent may not jump
// further in one step), validity flipped on every other frame, and every light after the current frame switched:
// nothing of it may change a rollout under SdcRule::model.
Scenario with_other_future(const Scenario& s) {
  Scenario out = s;
  for (Track& t : out.tracks)
    for (size_t f = s.current_time_index + 1; f < t.states.size(); ++f) {
      ObjectState& o = t.states[f];
      o.x += 3, o.y -= 2, o.heading = -o.heading, o.vx += 5;
      if (f % 2) o.valid = !o.valid;
    }
  for (size_t f = s.current_time_index + 1; f < out.signals.size(); ++f)
    for (SignalLaneState& l : out.signals[f]) l.state = l.state == SignalState::stop ? SignalState::go : SignalState::stop;
  return out;
}

void expect_same_steps(const std::vector<StepResult>& a, const std::vector<StepResult>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].agents.size(), b[k].agents.size()) << k;
    for (size_t i = 0; i < a[k].agents.size(); ++i) {
      EXPECT_EQ(a[k].agents[i].id, b[k].agents[i].id);
      EXPECT_EQ(a[k].agents[i].state, b[k].agents[i].state) << "step " << k << " agent " << a[k].agents[i].id;
    }
    ASSERT_EQ(a[k].lights.size(), b[k].lights.size());
    for (size_t i = 0; i < a[k].lights.size(); ++i) EXPECT_EQ(a[k].lights[i].state, b[k].lights[i].state);
  }
}

const AgentView* find_agent(const StepResult& r, int64_t id) {
  for (const AgentView& a : r.agents)
    if (a.id == id) return &a;
  return nullptr;
}

TEST(SdcRule, ModelRuleSessionSeesNoLoggedFuture) {
  const auto s = load("/womd/tfrecord/motion_data_one_scenario.tfrecord");  // has lights after the current frame
  const auto other = std::make_shared<const Scenario>(with_other_future(*s));
  ASSERT_NE(*s, *other);
  const auto model = small_model();
  MapCache maps(model);
  auto map = maps.get(*s);
  ASSERT_TRUE(map.ok()) << map.status();
  SessionOptions o;
  o.seed = 11;
  o.control_sdc = true;  // the rule overrides it
  const int steps = 6, now = s->current_time_index;
  const int64_t sdc_id = s->tracks[s->sdc_track_index].id;

  // The session's inputs: a scenario that ends at the current frame, no controlled agent, no control ever.
  RolloutInputs inputs;
  auto a = run_model_rollout(model, s, *map, o, SdcRule::model, steps, &inputs);
  ASSERT_TRUE(a.ok()) << a.status();
  ASSERT_TRUE(inputs.scenario);
  EXPECT_EQ(inputs.scenario->num_frames(), now + 1);
  for (const Track& t : inputs.scenario->tracks) EXPECT_EQ(static_cast<int>(t.states.size()), now + 1) << t.id;
  EXPECT_LE(static_cast<int>(inputs.scenario->signals.size()), now + 1);
  EXPECT_FALSE(inputs.options.control_sdc);
  EXPECT_TRUE(inputs.options.controlled_ids.empty());
  ASSERT_EQ(static_cast<int>(inputs.controls.size()), steps);
  for (const auto& c : inputs.controls) EXPECT_TRUE(c.empty());
  // The model drives the SDC: it is in the session, not controlled, at every step.
  for (const StepResult& r : *a) {
    const AgentView* sdc = find_agent(r, sdc_id);
    ASSERT_NE(sdc, nullptr) << "step " << r.step;
    EXPECT_FALSE(sdc->controlled);
  }
  // And as a black box: another logged future gives the very same rollout.
  auto b = run_model_rollout(model, other, *map, o, SdcRule::model, steps);
  ASSERT_TRUE(b.ok()) << b.status();
  expect_same_steps(*a, *b);

  // Under SdcRule::log the logged future does reach the session, through the SDC's controls (so the check above
  // can fail): the SDC is controlled and sits on its logged pose at every step.
  RolloutInputs log_inputs;
  auto c = run_model_rollout(model, other, *map, o, SdcRule::log, steps, &log_inputs);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(log_inputs.scenario->num_frames(), now + 1);
  int controlled_steps = 0;
  for (size_t k = 1; k < c->size(); ++k) {
    const int frame = (*c)[k].step * kFramesPerStep;
    const ObjectState& logged = other->tracks[other->sdc_track_index].states[frame];
    if (!logged.valid) continue;
    ++controlled_steps;
    ASSERT_EQ(log_inputs.controls[k - 1].size(), 1u);
    EXPECT_EQ(log_inputs.controls[k - 1][0].agent_id, sdc_id);
    const AgentView* sdc = find_agent((*c)[k], sdc_id);
    ASSERT_NE(sdc, nullptr);
    EXPECT_TRUE(sdc->controlled);
    EXPECT_NEAR(sdc->state.x, logged.x, 1e-6);
    EXPECT_NEAR(sdc->state.y, logged.y, 1e-6);
  }
  EXPECT_GT(controlled_steps, 0);
}

TEST(SdcRule, LogRuleLeavesTheSdcOutOfTheEvaluatedObjects) {
  // A scenario naming the SDC and tracks to predict, and a 20 s one naming only its SDC (every agent is scored).
  for (const char* path : {"/womd/tfrecord/motion_data_one_scenario.tfrecord", "/womd/json-20s/womd20s_92ddde4b.json"}) {
    SCOPED_TRACE(path);
    const auto s = load(path);
    ASSERT_GE(s->sdc_track_index, 0);
    const int64_t sdc_id = s->tracks[s->sdc_track_index].id;
    const EvaluatedObjects model_rule = evaluated_objects(*s, SdcRule::model);
    const EvaluatedObjects log_rule = evaluated_objects(*s, SdcRule::log);
    EXPECT_NE(std::find(model_rule.tracks.begin(), model_rule.tracks.end(), s->sdc_track_index), model_rule.tracks.end());
    EXPECT_EQ(std::find(log_rule.tracks.begin(), log_rule.tracks.end(), s->sdc_track_index), log_rule.tracks.end());
    EXPECT_EQ(log_rule.tracks.size() + 1, model_rule.tracks.size());

    EvalOptions o;
    o.policy = EvalPolicy::constant_velocity;
    o.rollouts = 1;
    o.sdc = SdcRule::log;
    auto log_eval = evaluate_scenario(s, o, nullptr, nullptr);
    ASSERT_TRUE(log_eval.ok()) << log_eval.status();
    o.sdc = SdcRule::model;
    auto model_eval = evaluate_scenario(s, o, nullptr, nullptr);
    ASSERT_TRUE(model_eval.ok()) << model_eval.status();
    EXPECT_EQ(log_eval->evaluated, static_cast<int>(log_rule.tracks.size()));
    EXPECT_EQ(log_eval->sdc_id, sdc_id);
    EXPECT_EQ(std::count(log_eval->evaluated_ids.begin(), log_eval->evaluated_ids.end(), sdc_id), 0);
    EXPECT_EQ(std::count(model_eval->evaluated_ids.begin(), model_eval->evaluated_ids.end(), sdc_id), 1);
    // The motion metrics leave it out too (it moves in the log of both files, so it has scored frames).
    EXPECT_EQ(log_eval->motion_all.agents + 1, model_eval->motion_all.agents);
  }
  // The 20 s files name their SDC but no track to predict: every agent valid now is evaluated, not the SDC alone.
  const auto s = load("/womd/json-20s/womd20s_92ddde4b.json");
  EXPECT_FALSE(evaluated_objects(*s).named_by_scenario);
  EXPECT_EQ(evaluated_objects(*s).tracks.size(), sim_agent_tracks(*s).size());
}

// A straight road, an SDC that brakes from 10 m/s to a stop over the 8 s, and three parked cars (two of them the
// tracks to predict): only the SDC moves.
std::shared_ptr<const Scenario> only_the_sdc_moves() {
  Scenario s;
  s.id = "only-sdc-moves";
  s.current_time_index = 10;
  for (int f = 0; f < 91; ++f) s.timestamps.push_back(0.1 * f);
  for (double y : {-6.0, 6.0}) {
    MapFeature edge;
    edge.id = static_cast<int64_t>(y > 0 ? 1 : 2);
    edge.kind = MapFeatureKind::road_edge;
    // Offroad is to the right of an edge's direction: the lower edge runs +x, the upper -x.
    edge.points = y < 0 ? std::vector<MapPoint>{{-300, y, 0}, {300, y, 0}} : std::vector<MapPoint>{{300, y, 0}, {-300, y, 0}};
    s.map_features.push_back(edge);
  }
  auto car = [&](int32_t id, double x, double y) {
    Track t;
    t.id = id;
    t.type = ObjectType::vehicle;
    for (int f = 0; f < 91; ++f) {
      ObjectState o;
      o.x = x, o.y = y, o.length = 4.5f, o.width = 2.0f, o.height = 1.6f, o.valid = true;
      t.states.push_back(o);
    }
    return t;
  };
  Track sdc = car(7, -50, -2);
  for (int f = 0; f < 91; ++f) {
    // 10 m/s until the current frame, then braking at 1.25 m/s^2 (stopped at frame 90).
    const double t = 0.1 * (f - 10);
    ObjectState& o = sdc.states[f];
    const double v = f <= 10 ? 10.0 : 10.0 - 1.25 * t;
    o.x = -50 + (f <= 10 ? 10.0 * t : 10.0 * t - 0.625 * t * t);
    o.vx = static_cast<float>(v);
  }
  s.tracks = {sdc, car(3, 0, 2.5), car(4, 30, 2.5), car(5, -80, 2.5)};
  s.sdc_track_index = 0;
  s.tracks_to_predict = {{1, 0}, {2, 0}};
  return std::make_shared<const Scenario>(std::move(s));
}

TEST(SdcRule, OnlyTheSdcMovesTheRulesScoreDifferently) {
  const auto s = only_the_sdc_moves();
  auto score = [&](EvalPolicy policy, SdcRule sdc) {
    EvalOptions o;
    o.policy = policy;
    o.sdc = sdc;
    o.rollouts = 4;
    auto r = evaluate_scenario(s, o, nullptr, nullptr);
    EXPECT_TRUE(r.ok()) << r.status();
    return *r;
  };
  const ScenarioEvaluation cv_model = score(EvalPolicy::constant_velocity, SdcRule::model);
  const ScenarioEvaluation cv_log = score(EvalPolicy::constant_velocity, SdcRule::log);
  const ScenarioEvaluation replay_model = score(EvalPolicy::log_replay, SdcRule::model);
  const ScenarioEvaluation replay_log = score(EvalPolicy::log_replay, SdcRule::log);
  EXPECT_EQ(cv_model.evaluated, 3);  // the SDC and the two tracks to predict
  EXPECT_EQ(cv_log.evaluated, 2);    // the two parked tracks to predict

  // --sdc log: the SDC follows its log and the parked cars stand still at constant (zero) velocity, so the
  // constant-velocity rollout IS the log: it scores exactly what log replay scores, with no displacement.
  EXPECT_DOUBLE_EQ(cv_log.realism.meta, replay_log.realism.meta);
  EXPECT_DOUBLE_EQ(cv_log.realism.min_ade, 0.0);
  // --sdc model: the constant-velocity policy drives the SDC too, which does not brake: it ends 40 m past its logged
  // stop. Its speed and acceleration leave the log's bins and its error is the whole ADE, so the score drops below
  // both log replay's and the log rule's.
  EXPECT_LT(cv_model.realism.meta, replay_model.realism.meta);
  EXPECT_LT(cv_model.realism.meta, cv_log.realism.meta);
  EXPECT_LT(cv_model.realism.kinematic, replay_model.realism.kinematic);
  EXPECT_GT(cv_model.realism.min_ade, 0.0);
  EXPECT_EQ(cv_model.motion_all.agents, 4);  // the SDC's final error (40 m) is the only one: a mean of 10 m
  EXPECT_NEAR(cv_model.motion_all.fde_min, 10.0, 1e-6);
  EXPECT_EQ(cv_log.motion_all.agents, 3);
  EXPECT_DOUBLE_EQ(cv_log.motion_all.fde_min, 0.0);
  // The parked cars' own terms are the same under both rules: scored alone (the log rule), constant velocity and log
  // replay agree exactly; the difference between the rules is the SDC's term.
  EXPECT_DOUBLE_EQ(cv_log.realism.likelihood[kLinearSpeed], replay_log.realism.likelihood[kLinearSpeed]);
}

}  // namespace
}  // namespace ss
