#include "engine/sim/tick.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "tests/unit/sim/session_fixture.h"

namespace ss {
namespace {

using testing::load_world;
using testing::same_result;
using testing::sdc_control;
using testing::start;

constexpr int kTicks = 5;  // 10 Hz ticks over 2 Hz model steps, as the server runs them

class TickTest : public testing::SmallWorldTest {};

const AgentView* find_agent(const StepResult& r, int64_t id) {
  for (const AgentView& a : r.agents)
    if (a.id == id) return &a;
  return nullptr;
}
const AgentView* find_agent(StepResult&& r, int64_t id) = delete;  // would point into a temporary

// Signed speed along the heading, as the kinematics carry it.
double speed_along_heading(const StepState& s) { return s.vx * std::cos(s.heading) + s.vy * std::sin(s.heading); }

// The path's end point is the pose the next model step gives every background agent: no jump at the step. Full mode
// too, so that agents the model adds at a step are covered from their first step on.
TEST_F(TickTest, LastSubTickIsTheNextStepsPose) {
  double max_position = 0, max_heading = 0, max_speed = 0;
  int compared = 0;
  for (SessionMode mode : {SessionMode::motion, SessionMode::full}) {
    SessionOptions o;
    o.mode = mode;
    o.seed = 3;
    auto s = start(w(), o);
    ASSERT_TRUE(s);
    for (int i = 0; i < 8; ++i) {
      // Any tick rate ends on the step: the server's 5 and others.
      const int ticks = i % 3 == 0 ? kTicks : (i % 3 == 1 ? 3 : 10);
      for (int k = 1; k < ticks; ++k) {
        const StepResult between = tick_between_steps(*s, k, ticks, {});
        EXPECT_NEAR(between.time, s->current().time + 0.5 * k / ticks, 1e-12);
        EXPECT_TRUE(between.left.empty());
        for (const AgentView& a : between.agents) EXPECT_FALSE(a.entered);
      }
      const StepResult predicted = tick_between_steps(*s, ticks, ticks, {});
      auto r = s->step({sdc_control(w(), s->step_index() + 1)});
      ASSERT_TRUE(r.ok()) << r.status();
      for (const AgentView& p : predicted.agents) {
        if (p.controlled) continue;
        const AgentView* a = find_agent(*r, p.id);
        if (!a) {  // retired at the step (left the region)
          EXPECT_NE(std::find(r->left.begin(), r->left.end(), p.id), r->left.end()) << "agent " << p.id;
          continue;
        }
        const double position = std::hypot(a->state.x - p.state.x, a->state.y - p.state.y);
        const double heading = std::abs(wrap_angle(a->state.heading - p.state.heading));
        const double speed = std::abs(speed_along_heading(a->state) - speed_along_heading(p.state));
        EXPECT_LE(position, 1e-6) << "agent " << p.id << " at step " << r->step;
        EXPECT_LE(heading, 1e-9) << "agent " << p.id << " at step " << r->step;
        EXPECT_LE(speed, 1e-9) << "agent " << p.id << " at step " << r->step;
        max_position = std::max(max_position, position);
        max_heading = std::max(max_heading, heading);
        max_speed = std::max(max_speed, speed);
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 100);
  std::printf("end point vs next step over %d agent-steps: max position error %.3g m, heading %.3g rad, speed %.3g m/s\n",
              compared, max_position, max_heading, max_speed);
}

// Between steps a forward-moving agent only moves on: away from where it started, towards where the step ends, with
// speed and heading changing at the sampled constant rates and the velocity along the heading.
TEST_F(TickTest, SubTicksProgressAlongThePath) {
  SessionOptions o;
  o.seed = 5;
  auto s = start(w(), o);
  ASSERT_TRUE(s);
  int checked = 0, moving = 0;
  for (int i = 0; i < 4; ++i) {
    std::vector<StepResult> views;
    for (int k = 0; k <= kTicks; ++k) views.push_back(tick_between_steps(*s, k, kTicks, {}));
    for (size_t j = 0; j < views[0].agents.size(); ++j) {
      if (views[0].agents[j].controlled) continue;
      bool forward = true;
      for (const StepResult& v : views) forward = forward && speed_along_heading(v.agents[j].state) >= 0;
      if (!forward) continue;
      const StepState& from = views[0].agents[j].state;
      const StepState& to = views[kTicks].agents[j].state;
      const double v0 = speed_along_heading(from), v1 = speed_along_heading(to);
      const double turn = wrap_angle(to.heading - from.heading);
      double last_from_start = 0, last_to_end = std::numeric_limits<double>::infinity();
      for (int k = 1; k <= kTicks; ++k) {
        const StepState& p = views[k].agents[j].state;
        const double from_start = std::hypot(p.x - from.x, p.y - from.y);
        const double to_end = std::hypot(p.x - to.x, p.y - to.y);
        EXPECT_GE(from_start, last_from_start - 1e-12) << "agent " << views[0].agents[j].id << " tick " << k;
        EXPECT_LE(to_end, last_to_end + 1e-12) << "agent " << views[0].agents[j].id << " tick " << k;
        last_from_start = from_start;
        last_to_end = to_end;
        EXPECT_NEAR(speed_along_heading(p), v0 + (v1 - v0) * k / kTicks, 1e-9);
        EXPECT_NEAR(wrap_angle(p.heading - from.heading - turn * k / kTicks), 0, 1e-9);
        EXPECT_NEAR(p.vx * std::sin(p.heading) - p.vy * std::cos(p.heading), 0, 1e-9);  // no sideways velocity
      }
      ++checked;
      if (last_from_start > 0.1) ++moving;
    }
    ASSERT_TRUE(s->step({sdc_control(w(), s->step_index() + 1)}).ok());
  }
  EXPECT_GT(checked, 20);
  EXPECT_GT(moving, 10);
}

TEST_F(TickTest, ControlledAgentShowsItsPushedPose) {
  auto s = start(w(), {});
  ASSERT_TRUE(s);
  const StepResult at_step = s->current();
  const auto ego = std::find_if(at_step.agents.begin(), at_step.agents.end(), [](const AgentView& a) { return a.controlled; });
  ASSERT_NE(ego, at_step.agents.end());
  ControlInput pushed{ego->id, ego->state.x + 0.7, ego->state.y - 0.2, ego->state.heading + 0.05, 6.0};
  for (int k = 1; k < kTicks; ++k) {
    const StepResult view = tick_between_steps(*s, k, kTicks, {pushed});
    const AgentView* a = find_agent(view, ego->id);
    ASSERT_TRUE(a);
    EXPECT_EQ(a->state.x, pushed.x);
    EXPECT_EQ(a->state.y, pushed.y);
    EXPECT_EQ(a->state.heading, pushed.heading);
    EXPECT_NEAR(speed_along_heading(a->state), 6.0, 1e-12);
  }
  // Without a speed the pushed pose keeps the step's velocity; without a push the agent stays at its step pose.
  pushed.speed.reset();
  const StepResult without_speed = tick_between_steps(*s, 2, kTicks, {pushed});
  const AgentView* a = find_agent(without_speed, ego->id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->state.x, pushed.x);
  EXPECT_EQ(a->state.vx, ego->state.vx);
  EXPECT_EQ(a->state.vy, ego->state.vy);
  const StepResult without_push = tick_between_steps(*s, 2, kTicks, {});
  a = find_agent(without_push, ego->id);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->state, ego->state);
}

// A pending StateForce teleports the agent at the next step, not before: until then it moves on at its velocity of
// the last step (the control it sampled will not be applied).
TEST_F(TickTest, StateForcedAgentDoesNotJumpBeforeTheStep) {
  auto s = start(w(), {});
  ASSERT_TRUE(s);
  ASSERT_TRUE(s->step({sdc_control(w(), 3)}).ok());
  const StepResult at_step = s->current();
  // The fastest background agent, so that "moves on at its velocity" is visible.
  const AgentView* other = nullptr;
  for (const AgentView& a : at_step.agents)
    if (!a.controlled && (!other || std::hypot(a.state.vx, a.state.vy) > std::hypot(other->state.vx, other->state.vy)))
      other = &a;
  ASSERT_TRUE(other);
  ASSERT_GT(std::hypot(other->state.vx, other->state.vy), 0.5);
  // 72 m away: between the steps the agent moves on at its own velocity, far from the target. Of the four
  // directions, one that keeps the target inside the SDC's region (else the agent would retire at the step).
  const AgentView* sdc = nullptr;
  for (const AgentView& a : at_step.agents)
    if (a.controlled) sdc = &a;
  ASSERT_TRUE(sdc);
  StepState target = other->state;
  for (const auto [dx, dy] : {std::pair{60.0, -40.0}, {-60.0, 40.0}, {60.0, 40.0}, {-60.0, -40.0}}) {
    target.x = other->state.x + dx;
    target.y = other->state.y + dy;
    if (std::hypot(target.x - sdc->state.x, target.y - sdc->state.y) < 90) break;
  }
  ASSERT_LT(std::hypot(target.x - sdc->state.x, target.y - sdc->state.y), 90);
  StateForceRequest req;
  req.agents = {{other->id, target}};
  ASSERT_TRUE(s->state_force(req).ok());
  for (int k = 1; k <= kTicks; ++k) {
    const double t = 0.5 * k / kTicks;
    const StepResult view = tick_between_steps(*s, k, kTicks, {});
    const AgentView* a = find_agent(view, other->id);
    ASSERT_TRUE(a);
    EXPECT_NEAR(a->state.x, other->state.x + other->state.vx * t, 1e-9);
    EXPECT_NEAR(a->state.y, other->state.y + other->state.vy * t, 1e-9);
    EXPECT_EQ(a->state.heading, other->state.heading);
    EXPECT_GT(std::hypot(a->state.x - target.x, a->state.y - target.y), 40);
  }
  auto r = s->step({sdc_control(w(), 4)});
  ASSERT_TRUE(r.ok()) << r.status();
  const AgentView* after = find_agent(*r, other->id);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->state, target);
}

// The sub-tick path depends only on what a session saves (its sampled controls), so a restored or forked session, as
// the server makes after an eviction, shows the same ticks.
TEST_F(TickTest, RestoredAndForkedSessionsShowTheSameSubTicks) {
  auto s = start(w(), {});
  ASSERT_TRUE(s);
  ASSERT_TRUE(s->step({sdc_control(w(), 3)}).ok());
  auto restored = Session::restore(w().model, w().scenario, w().map, s->save());
  ASSERT_TRUE(restored.ok()) << restored.status();
  auto forked = s->fork();
  for (int k = 1; k <= kTicks; ++k) {
    const StepResult original = tick_between_steps(*s, k, kTicks, {});
    EXPECT_TRUE(same_result(original, tick_between_steps(**restored, k, kTicks, {}))) << "tick " << k;
    EXPECT_TRUE(same_result(original, tick_between_steps(*forked, k, kTicks, {}))) << "tick " << k;
  }
}

}  // namespace
}  // namespace ss
