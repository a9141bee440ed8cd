#include "engine/sim/rule_agents.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "engine/tokens/fidelity.h"
#include "tests/unit/sim/session_fixture.h"

namespace ss {
namespace {

using testing::sdc_control;
using testing::start;

TEST(Idm, FreeRoadAndFollowingAccelerations) {
  const IdmParams p;
  EXPECT_DOUBLE_EQ(idm_acceleration(p, 0, 10, INFINITY, 0), p.max_accel);  // from rest, nothing ahead
  EXPECT_NEAR(idm_acceleration(p, 10, 10, INFINITY, 0), 0, 1e-12);        // at the desired speed
  // Following at the leader's speed at exactly the desired gap s* = s0 + v T: a (1 - (v/v0)^4 - 1).
  const double v = 10, v0 = 20, gap = p.min_gap + v * p.headway;
  EXPECT_NEAR(idm_acceleration(p, v, v0, gap, v), -p.max_accel * std::pow(v / v0, 4), 1e-12);
  EXPECT_DOUBLE_EQ(idm_acceleration(p, 10, 10, 0.0, 0), -p.max_brake);     // touching
  EXPECT_DOUBLE_EQ(idm_acceleration(p, 30, 30, 3.0, 0), -p.max_brake);     // far too close: clamped
  EXPECT_DOUBLE_EQ(idm_acceleration(p, 2, 0.0, INFINITY, 0), -p.comfort_brake);  // the log stops: brake at b
}

Track straight_track(int frames, double speed) {
  Track t;
  t.id = 3;
  t.type = ObjectType::vehicle;
  for (int f = 0; f < frames; ++f) {
    ObjectState o;
    o.x = f * speed * 0.1, o.y = 0, o.heading = 0, o.vx = speed, o.length = 4.5, o.width = 2, o.height = 1.5;
    o.valid = true;
    t.states.push_back(o);
  }
  return t;
}

TEST(LoggedPath, PosesAlongAndBeyondThePath) {
  Track t = straight_track(11, 10);  // x = 0 .. 10
  t.states[5].valid = false;
  t.states.push_back(t.states.back());  // a standing frame: no zero-length segment
  const LoggedPath p = logged_path(t);
  EXPECT_EQ(p.points.size(), 10u);
  EXPECT_DOUBLE_EQ(p.s.back(), 10.0);
  EXPECT_NEAR(path_pose(p, 4.5).x, 4.5, 1e-12);
  EXPECT_NEAR(path_pose(p, 12).x, 12, 1e-12);  // straight on past the end
  EXPECT_NEAR(path_pose(p, -1).x, -1, 1e-12);
  EXPECT_DOUBLE_EQ(path_s_at_frame(p, 5), 4.0);  // frame 5 invalid: the last valid frame before it
  EXPECT_DOUBLE_EQ(path_s_at_frame(p, 11), 10.0);
}

TEST(Idm, StopsBehindAStandingCarWithoutTouchingIt) {
  const IdmParams p;
  const LoggedPath path = logged_path(straight_track(91, 10));  // x = 0 .. 90
  const IdmOther standing{{{40, 0, 0}, 4.5, 2}, {0, 0}};
  double s = 0, v = 10;
  for (int k = 0; k < 40; ++k) {
    const IdmMove m = idm_step(p, path, s, v, 10, 4.5, 2, {&standing, 1}, 0.5);
    s = m.s, v = m.speed;
  }
  EXPECT_LT(v, 0.1);
  const double gap = 40 - 2.25 - (s + 2.25);
  EXPECT_GT(gap, 0.5);
  EXPECT_LT(gap, p.min_gap + 1.0);
}

class RuleModeTest : public testing::SmallWorldTest {};

TEST_F(RuleModeTest, LogModeReplaysTheLogAndFollowsItsValidity) {
  SessionOptions o;
  o.mode = SessionMode::log;
  auto s = start(w(), o);
  ASSERT_TRUE(s);
  const Scenario& sc = *w().scenario;
  for (int k = 0; k < 16; ++k) {
    const StepResult r = s->current();
    const int frame = r.step * 5;
    int expected = 0;
    for (const Track& t : sc.tracks) expected += model_type(t.type) >= 0 && t.states[frame].valid;
    EXPECT_EQ(static_cast<int>(r.agents.size()), expected) << "step " << r.step;
    for (const AgentView& a : r.agents) {
      const Track* t = nullptr;
      for (const Track& x : sc.tracks)
        if (x.id == a.id) t = &x;
      ASSERT_NE(t, nullptr);
      EXPECT_TRUE(t->states[frame].valid);
      if (a.controlled) continue;
      EXPECT_DOUBLE_EQ(a.state.x, t->states[frame].x);
      EXPECT_DOUBLE_EQ(a.state.y, t->states[frame].y);
    }
    auto next = s->step({sdc_control(w(), r.step + 1)});
    ASSERT_TRUE(next.ok()) << next.status();
  }
}

TEST_F(RuleModeTest, IdmVehiclesStayOnTheirPathAndStopBehindAStoppedEgo) {
  SessionOptions o;
  o.mode = SessionMode::idm;
  auto s = start(w(), o);
  ASSERT_TRUE(s);
  const Scenario& sc = *w().scenario;
  const int64_t ego = sc.tracks[sc.sdc_track_index].id;
  std::map<int64_t, LoggedPath> paths;
  for (const Track& t : sc.tracks) paths[t.id] = logged_path(t);
  for (int k = 0; k < 16; ++k) {
    // The ego stops where it is: whatever drives behind it must stop too.
    const StepResult now = s->current();
    ControlInput hold;
    for (const AgentView& a : now.agents)
      if (a.id == ego) hold = {ego, a.state.x, a.state.y, a.state.heading, 0.0};
    auto r = s->step({hold});
    ASSERT_TRUE(r.ok()) << r.status();
    const AgentView* e = nullptr;
    for (const AgentView& a : r->agents)
      if (a.id == ego) e = &a;
    ASSERT_NE(e, nullptr);
    for (const AgentView& a : r->agents) {
      if (a.controlled || a.type != 0 || a.entered) continue;
      // On its own logged path, extended straight beyond its ends as path_pose extends it.
      const LoggedPath& path = paths[a.id];
      std::vector<Vec2> pts = path.points;
      const Pose before = path_pose(path, -100), after = path_pose(path, path.s.back() + 100);
      pts.insert(pts.begin(), Vec2{before.x, before.y});
      pts.push_back({after.x, after.y});
      EXPECT_LT(point_polyline_distance({a.state.x, a.state.y}, pts), 1e-6) << "agent " << a.id;
    }
  }
  // Nothing that moved under IDM ended inside the stopped ego (the log's own overlaps aside, none here).
  const StepResult last = s->current();
  const AgentView* e = nullptr;
  for (const AgentView& a : last.agents)
    if (a.id == ego) e = &a;
  for (const AgentView& a : last.agents)
    if (a.id != ego && a.type == 0)
      EXPECT_FALSE(boxes_overlap({{e->state.x, e->state.y, e->state.heading}, e->state.length, e->state.width},
                                 {{a.state.x, a.state.y, a.state.heading}, a.state.length, a.state.width}))
          << "agent " << a.id;
}

TEST_F(RuleModeTest, RuleSessionsRestoreAndContinueIdentically) {
  for (SessionMode mode : {SessionMode::log, SessionMode::idm}) {
    SessionOptions o;
    o.mode = mode;
    auto a = start(w(), o);
    ASSERT_TRUE(a);
    for (int k = 0; k < 4; ++k) ASSERT_TRUE(a->step({sdc_control(w(), a->step_index() + 1)}).ok());
    auto b = Session::restore(w().model, w().scenario, w().map, a->save());
    ASSERT_TRUE(b.ok()) << b.status();
    for (int k = 0; k < 6; ++k) {
      auto ra = a->step({sdc_control(w(), a->step_index() + 1)});
      auto rb = (*b)->step({sdc_control(w(), (*b)->step_index() + 1)});
      ASSERT_TRUE(ra.ok() && rb.ok());
      EXPECT_TRUE(testing::same_result(*ra, *rb)) << session_mode_name(mode) << " step " << ra->step;
    }
  }
}

TEST_F(RuleModeTest, RuleSessionsRefuseWhatNeedsTheModel) {
  SessionOptions o;
  o.mode = SessionMode::idm;
  auto s = start(w(), o);
  ASSERT_TRUE(s);
  InjectRequest inject;
  inject.count = 1;
  auto ids = s->inject(inject);
  ASSERT_FALSE(ids.ok());
  EXPECT_EQ(ids.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(std::string(ids.status().message()).find("idm session"), std::string::npos);
  // Moving a log-driven agent is refused; the controlled ego can be placed.
  const StepResult r = s->current();
  StateForceRequest force;
  for (const AgentView& a : r.agents)
    if (!a.controlled) {
      force.agents.push_back({a.id, a.state});
      break;
    }
  const absl::Status st = s->state_force(force);
  EXPECT_EQ(st.code(), absl::StatusCode::kFailedPrecondition) << st;
  StateForceRequest ego;
  for (const AgentView& a : r.agents)
    if (a.controlled) ego.agents.push_back({a.id, a.state});
  EXPECT_TRUE(s->state_force(ego).ok());
}

TEST(SessionModeNames, RoundTrip) {
  for (SessionMode m : {SessionMode::motion, SessionMode::full, SessionMode::densify, SessionMode::log, SessionMode::idm})
    EXPECT_EQ(session_mode_from_name(session_mode_name(m)), m);
  EXPECT_FALSE(session_mode_from_name("replay"));
}

}  // namespace
}  // namespace ss
