// Teacher-forced examples: the layout of each step, every head's target against the tokens that follow, the key
// lists against the mask, phases, the agent cap and the errors.
#include "engine/sim/teacher_forcing.h"

#include <gtest/gtest.h>

#include <set>

#include "engine/model/mask.h"
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
  const TeacherForcedExample ex = example();
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

}  // namespace
}  // namespace ss
