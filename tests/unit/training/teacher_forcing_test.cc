// Teacher-forced examples: the layout of each step, every head's target against the tokens that follow, the key
// lists against the mask, phases, the agent cap and the errors. Closed-loop (CAT-K) examples: the policy's own
// choice among its top K moves each agent, the targets are re-tokenised toward the log, and with every token allowed
// the rollout is the log's tokenization.
#include "training/teacher_forcing.h"

#include <gtest/gtest.h>

#include <map>
#include <set>

#include "engine/geometry/geometry.h"
#include "engine/model/mask.h"
#include "engine/model/model.h"
#include "engine/scenario/read.h"
#include "engine/sim/token_builders.h"
#include "engine/tokens/motion.h"

namespace ss {
namespace {

const Scenario& real_scenario() {
  static const Scenario s = [] {
    auto v = read_scenarios(std::string(SS_DATA_DIR) + "/womd/tfrecord/motion_data_one_scenario.tfrecord");
    EXPECT_TRUE(v.ok()) << v.status();
    return (*v)[0];
  }();
  return s;
}

ModelConfig config() { return *model_config_by_name("small"); }

TeacherForcedExample example(TeacherForcingOptions o = {}) {
  auto ex = teacher_forced_example(real_scenario(), config(), o);
  EXPECT_TRUE(ex.ok()) << ex.status();
  return *ex;
}

TEST(TeacherForcing, EachStepIsLightsThenTheGroupThenMotion) {
  const TeacherForcedExample ex = example();
  ASSERT_EQ(ex.steps, 19);
  size_t i = 0;
  int lights = -1;
  for (int t = 0; t < ex.steps; ++t) {
    int n = 0;
    for (; i < ex.tokens.size() && ex.tokens[i].kind == TokenKind::light; ++i, ++n) EXPECT_EQ(ex.tokens[i].step, t);
    if (lights < 0) lights = n;
    EXPECT_EQ(n, lights) << "every step has the same lights";
    ASSERT_EQ(ex.tokens[i].kind, TokenKind::sos);
    ++i;
    int agents = 0;
    for (; ex.tokens[i].kind == TokenKind::soa; i += 4, ++agents) {
      EXPECT_EQ(ex.tokens[i + 1].kind, TokenKind::type);
      EXPECT_EQ(ex.tokens[i + 2].kind, TokenKind::map_segment);
      EXPECT_EQ(ex.tokens[i + 3].kind, TokenKind::relative_state);
      EXPECT_EQ(ex.tokens[i].intra_index, 4 * agents);
    }
    ASSERT_EQ(ex.tokens[i++].kind, TokenKind::eos);
    for (int a = 0; a < agents; ++a, ++i) ASSERT_EQ(ex.tokens[i].kind, TokenKind::motion);
  }
  EXPECT_EQ(i, ex.tokens.size());
  EXPECT_GT(lights, 0) << "the real TFRecord has signals";
  for (size_t j = 0; j < ex.tokens.size(); ++j) EXPECT_EQ(ex.tokens[j].seq, static_cast<int64_t>(j));
}

TEST(TeacherForcing, TargetsAreWhatTheSequenceDoesNext) {
  TeacherForcingOptions o;
  o.max_agents = config().agent_slots;  // no agent left out: every step's end of agents is the log's
  const TeacherForcedExample ex = example(o);
  const auto& tok = ex.tokens;
  // Where each object's motion and light tokens are, by step.
  std::map<std::pair<int64_t, int>, int> at;
  for (size_t i = 0; i < tok.size(); ++i)
    if (tok[i].kind == TokenKind::motion || tok[i].kind == TokenKind::light) at[{tok[i].object, tok[i].step}] = i;
  int motion_targets = 0, light_targets = 0;
  for (size_t i = 0; i < tok.size(); ++i) {
    const DecoderToken& t = tok[i];
    switch (t.kind) {
      case TokenKind::motion: {
        if (ex.motion_target[i] != kNoTarget) {
          ++motion_targets;
          const auto next = at.find({t.object, t.step + 1});
          ASSERT_NE(next, at.end());
          EXPECT_EQ(tok[next->second].motion_action, ex.motion_target[i]) << "the token that brings it there";
          EXPECT_LT(ex.motion_target[i], kMotionVocab);
        }
        break;
      }
      case TokenKind::light: {
        if (t.step + 1 < ex.steps) {
          ++light_targets;
          const auto next = at.find({t.object, t.step + 1});
          ASSERT_NE(next, at.end());
          EXPECT_EQ(tok[next->second].light_state, ex.light_target[i]);
        } else {
          EXPECT_EQ(ex.light_target[i], kNoTarget);
        }
        break;
      }
      case TokenKind::sos: EXPECT_EQ(ex.end_target[i], tok[i + 1].kind == TokenKind::soa ? 0 : 1); break;
      case TokenKind::soa: EXPECT_EQ(ex.type_target[i], t.agent_type); break;
      case TokenKind::type: EXPECT_EQ(ex.segment_target[i], tok[i + 1].map_id); break;
      case TokenKind::map_segment:
        for (int f = 0; f < kRsFields; ++f)  // the RS token's input is the bins scaled to [-1, 1]
          EXPECT_FLOAT_EQ(2.0f * ex.state_target[i][f] / (kRsBins - 1) - 1.0f, tok[i + 1].relative_state[f]);
        break;
      case TokenKind::relative_state: EXPECT_EQ(ex.end_target[i], tok[i + 1].kind == TokenKind::soa ? 0 : 1); break;
      case TokenKind::eos: break;
    }
    if (t.kind != TokenKind::motion) {
      EXPECT_EQ(ex.motion_target[i], kNoTarget);
    }
  }
  EXPECT_GT(motion_targets, 100);
  EXPECT_GT(light_targets, 100);
}

TEST(TeacherForcing, KeysAreTokensTheMaskAllows) {
  const TeacherForcedExample ex = example();
  const int window = config().window_steps;
  ASSERT_EQ(ex.self_keys.offsets.size(), ex.tokens.size() + 1);
  ASSERT_EQ(ex.self_keys.features.size(), ex.self_keys.keys.size() * kRelationFeatures);
  for (size_t i = 0; i < ex.tokens.size(); ++i) {
    std::set<int> seen;
    for (int e = ex.self_keys.offsets[i]; e < ex.self_keys.offsets[i + 1]; ++e) {
      const int j = ex.self_keys.keys[e];
      // Later keys only where a step's lights (or motion tokens) read each other, decoded in one batch.
      if (j > static_cast<int>(i)) {
        EXPECT_EQ(ex.tokens[j].step, ex.tokens[i].step);
        EXPECT_EQ(ex.tokens[j].kind, ex.tokens[i].kind);
        EXPECT_TRUE(ex.tokens[i].kind == TokenKind::light || ex.tokens[i].kind == TokenKind::motion);
      }
      EXPECT_TRUE(may_attend(ex.tokens[i], ex.tokens[j], window)) << i << " -> " << j;
      EXPECT_TRUE(seen.insert(j).second) << "key listed twice";
    }
    // Posed tokens read their nearest segments; the others read the whole map (no list).
    const int cross = ex.cross_keys.offsets[i + 1] - ex.cross_keys.offsets[i];
    if (ex.tokens[i].has_pose) {
      EXPECT_GE(cross, config().knn_always);
      EXPECT_LE(cross, config().knn_k);
    } else {
      EXPECT_EQ(cross, 0);
    }
  }
  EXPECT_EQ(ex.map_keys.offsets.size(), ex.segments.size() + 1);
}

TEST(TeacherForcing, FivePhasesOfOneLog) {
  const int want[] = {19, 18, 18, 18, 18};
  std::set<double> first_x;
  for (int phase = 0; phase < 5; ++phase) {
    TeacherForcingOptions o;
    o.phase = phase;
    const TeacherForcedExample ex = example(o);
    EXPECT_EQ(ex.steps, want[phase]);
    for (const DecoderToken& t : ex.tokens)
      if (t.kind == TokenKind::motion) {
        first_x.insert(t.pose.x);
        break;
      }
  }
  EXPECT_EQ(first_x.size(), 5u) << "each phase starts from a different frame";
}

TEST(TeacherForcing, AgentCapSlotsAndDeterminism) {
  TeacherForcingOptions o;
  o.max_agents = 5;
  const TeacherForcedExample ex = example(o);
  std::set<int64_t> objects;
  std::vector<int> slots;
  for (const DecoderToken& t : ex.tokens)
    if (t.kind == TokenKind::soa && objects.insert(t.object).second) slots.push_back(t.agent_slot);
  EXPECT_EQ(ex.agents, 5);
  EXPECT_EQ(objects.size(), 5u);
  EXPECT_TRUE(objects.count(real_scenario().tracks[real_scenario().sdc_track_index].id)) << "the SDC comes first";
  for (size_t k = 0; k < slots.size(); ++k) EXPECT_EQ(slots[k], static_cast<int>(k)) << "slots in order of entry";
  o.slot_seed = 9;
  const TeacherForcedExample a = example(o), b = example(o);
  EXPECT_EQ(a.self_keys.keys, b.self_keys.keys);
  EXPECT_EQ(a.motion_target, b.motion_target);
  std::set<int> drawn;
  for (const DecoderToken& t : a.tokens)
    if (t.kind == TokenKind::soa) drawn.insert(t.agent_slot);
  EXPECT_NE(drawn, std::set<int>({0, 1, 2, 3, 4})) << "a seed draws the slots";
}

// With agents left out, the scene goes on after the last one kept: that step's end of agents has no target (else
// the model learns that scenes end at the cap). Uncapped, every step ends with 1.
TEST(TeacherForcing, AnEndAtTheAgentCapIsNotATarget) {
  auto ends = [](const TeacherForcedExample& ex) {
    std::vector<int> out;  // each step's last end target (the SOS's when no agent is alive)
    for (size_t i = 0; i < ex.tokens.size(); ++i)
      if (ex.tokens[i].kind == TokenKind::eos) out.push_back(ex.end_target[i - 1]);
    return out;
  };
  TeacherForcingOptions o;
  o.max_agents = config().agent_slots;
  const TeacherForcedExample all = example(o);
  ASSERT_GT(all.agents, 5);
  EXPECT_EQ(ends(all), std::vector<int>(all.steps, 1));
  o.max_agents = 5;
  const TeacherForcedExample capped = example(o);
  EXPECT_EQ(ends(capped), std::vector<int>(capped.steps, kNoTarget));
  int zeros = 0;
  for (int e : capped.end_target) zeros += e == 0;
  EXPECT_GT(zeros, 4 * capped.steps) << "the agents kept still say that another follows";
}

TEST(TeacherForcing, BadInputsAreRefused) {
  TeacherForcingOptions o;
  o.phase = 5;
  EXPECT_EQ(teacher_forced_example(real_scenario(), config(), o).status().code(), absl::StatusCode::kInvalidArgument);
  o.phase = 0;
  o.max_agents = 0;
  EXPECT_EQ(teacher_forced_example(real_scenario(), config(), o).status().code(), absl::StatusCode::kInvalidArgument);
  Scenario short_log = real_scenario();
  short_log.timestamps.resize(3);
  for (Track& t : short_log.tracks) t.states.resize(3);
  short_log.signals.resize(3);
  auto r = teacher_forced_example(short_log, config(), {});
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("fewer than two steps"), std::string_view::npos) << r.status();
  Scenario no_map = real_scenario();
  no_map.map_features.clear();
  EXPECT_EQ(teacher_forced_example(no_map, config(), {}).status().code(), absl::StatusCode::kFailedPrecondition);
}

// fp32 products: the argmax check below compares the rollout's incremental logits with a full recompute to 1e-4,
// fp32's bound (bf16 rounding can move a logit by more: tests/unit/sim/precision_test.cc).
const Model& policy() {
  static const std::shared_ptr<const Model> m = [] {
    ModelOptions o;
    o.matmul_precision = MatmulPrecision::fp32;
    return *Model::create(init_weights(*model_config_by_name("small"), 3), o);
  }();
  return *m;
}

TeacherForcingOptions options() {
  TeacherForcingOptions o;
  o.max_agents = 12;
  return o;
}

TeacherForcedExample closed(int top_k) {
  auto ex = closed_loop_example(real_scenario(), policy(), options(), top_k);
  EXPECT_TRUE(ex.ok()) << ex.status();
  return *ex;
}

// Index of each object's motion token at each step.
std::map<std::pair<int64_t, int>, int> motion_at(const TeacherForcedExample& ex) {
  std::map<std::pair<int64_t, int>, int> at;
  for (size_t i = 0; i < ex.tokens.size(); ++i)
    if (ex.tokens[i].kind == TokenKind::motion) at[{ex.tokens[i].object, ex.tokens[i].step}] = static_cast<int>(i);
  return at;
}

TEST(ClosedLoop, TopOneMovesEachAgentByThePolicysArgmax) {
  TeacherForcedExample ex = closed(1);
  // The whole sequence recomputed at once gives the logits each step's choice was made from.
  const Mat logits = policy().motion_logits(policy().decode_full(**policy().encode_map(ex.segments), ex.tokens));
  const auto at = motion_at(ex);
  int checked = 0;
  for (const auto& [key, i] : at) {
    const auto next = at.find({key.first, key.second + 1});
    if (next == at.end()) continue;
    const int chosen = ex.tokens[next->second].motion_action;
    ASSERT_GE(chosen, 0);
    ASSERT_LT(chosen, kMotionVocab);
    EXPECT_GE(logits(i, chosen), logits.row(i).maxCoeff() - 1e-4) << "step " << key.second << ", object " << key.first;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(ClosedLoop, TargetsLeadFromTheRolledOutStateToTheLog) {
  const TeacherForcedExample ex = closed(4);
  std::map<int64_t, const Track*> track_of;
  for (const Track& t : real_scenario().tracks) track_of[t.id] = &t;
  const auto at = motion_at(ex);
  int targets = 0, differ = 0;
  for (size_t i = 0; i < ex.tokens.size(); ++i) {
    const DecoderToken& t = ex.tokens[i];
    if (t.kind != TokenKind::motion || ex.motion_target[i] == kNoTarget) continue;
    const ObjectState& next = track_of.at(t.object)->states[ex.phase + 5 * (t.step + 1)];
    ASSERT_TRUE(next.valid);
    const KinematicState from{t.pose.x, t.pose.y, t.pose.heading, t.motion_state[0] * 10.0};  // local vx / 10
    const Box log_box{{next.x, next.y, next.heading}, next.length, next.width};
    auto ace = [&](int token) {
      const KinematicState s = apply_motion_token(from, token);
      return average_corner_error({{s.x, s.y, s.heading}, next.length, next.width}, log_box);
    };
    // The token state is stored in floats: the target is the best token within that rounding.
    EXPECT_LE(ace(ex.motion_target[i]), fit_motion_token(from, {next.x, next.y, next.heading}, next.length, next.width).ace + 1e-3);
    ++targets;
    const auto n = at.find({t.object, t.step + 1});
    if (n != at.end() && ex.tokens[n->second].motion_action != ex.motion_target[i]) ++differ;
  }
  EXPECT_GT(targets, 100);
  EXPECT_GT(differ, 0) << "a random policy's top 4 rarely holds the log's token: targets and inputs part";
}

TEST(ClosedLoop, EveryTokenAllowedFollowsTheLogsTokenization) {
  const TeacherForcedExample ex = closed(kMotionVocab);
  auto tf = teacher_forced_example(real_scenario(), policy().config(), options());
  ASSERT_TRUE(tf.ok()) << tf.status();
  ASSERT_EQ(ex.tokens.size(), tf->tokens.size());
  int motion = 0, same = 0;
  for (size_t i = 0; i < ex.tokens.size(); ++i) {
    if (ex.tokens[i].kind != TokenKind::motion) continue;
    ++motion;
    same += ex.tokens[i].motion_action == tf->tokens[i].motion_action && ex.motion_target[i] == tf->motion_target[i];
  }
  // Only the tokenizer's centre preference (1e-5 m per bin) can part the two.
  EXPECT_GE(same, motion * 99 / 100) << same << " of " << motion;
  EXPECT_EQ(ex.light_target, tf->light_target);
  EXPECT_EQ(ex.end_target, tf->end_target);
  EXPECT_EQ(ex.type_target, tf->type_target);
}

TEST(ClosedLoop, BadTopKIsRefused) {
  auto r = closed_loop_example(real_scenario(), policy(), options(), 0);
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("top_k"), std::string_view::npos) << r.status();
}

}  // namespace
}  // namespace ss
