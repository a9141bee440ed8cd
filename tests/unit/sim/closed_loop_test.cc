// CAT-K examples (closed_loop_example): the policy's own choice among its top K moves each agent, the targets are
// re-tokenised toward the log, and with every token allowed the rollout is the log's tokenization.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "engine/geometry/geometry.h"
#include "engine/model/model.h"
#include "engine/scenario/read.h"
#include "engine/sim/teacher_forcing.h"
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

const Model& policy() {
  static const std::shared_ptr<const Model> m = *Model::create(init_weights(*model_config_by_name("small"), 3));
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
