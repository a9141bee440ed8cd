#include "offline/eval/ego_loop.h"

#include <gtest/gtest.h>

#include <cmath>

namespace ss {
namespace {

StepState car(double x, double y, double heading, double speed) {
  StepState s;
  s.x = x, s.y = y, s.heading = heading;
  s.vx = speed * std::cos(heading), s.vy = speed * std::sin(heading);
  s.length = 4.5, s.width = 2.0, s.height = 1.5, s.valid = true;
  return s;
}

StepResult step(int k, std::vector<std::pair<int64_t, StepState>> agents) {
  StepResult r;
  r.step = k;
  for (auto& [id, s] : agents) r.agents.push_back({id, 0, s, id == 1, false});
  return r;
}

TEST(EgoCollision, AnAgentForcedIntoABrakingEgoFromBehindIsARearEnd) {
  // The ego brakes from 10 m/s; the agent behind keeps 10 m/s and closes the 5 m gap.
  const std::vector<StepResult> steps = {step(0, {{1, car(0, 0, 0, 10)}, {2, car(-9.5, 0, 0, 10)}}),
                                         step(1, {{1, car(3, 0, 0, 2)}, {2, car(-4.5, 0, 0, 10)}}),
                                         step(2, {{1, car(3.5, 0, 0, 0)}, {2, car(0.5, 0, 0, 10)}})};
  const EgoOutcome o = ego_outcome(steps, 1, false);
  EXPECT_EQ(o.collision, EgoCollision::rear_end);
  EXPECT_EQ(o.collision_step, 2);
  EXPECT_EQ(o.collision_with, 2);
  EXPECT_EQ(o.steps, 2);
}

TEST(EgoCollision, TheEgoDrivingIntoAStandingCarIsTheEgosFault) {
  EXPECT_EQ(classify_ego_collision(car(0, 0, 0, 10), car(4, 0.3, 0.05, 0)), EgoCollision::ego_at_fault);
  // Into another's side at a right angle: still the ego's front that strikes.
  EXPECT_EQ(classify_ego_collision(car(0, 0, 0, 10), car(3.5, 0, M_PI / 2, 5)), EgoCollision::ego_at_fault);
}

TEST(EgoCollision, AnotherFrontIntoTheEgosSideIsASideImpact) {
  // A car coming from the ego's left (heading -90 degrees) with its front in the ego's left flank.
  EXPECT_EQ(classify_ego_collision(car(0, 0, 0, 5), car(0.5, 3, -M_PI / 2, 8)), EgoCollision::side);
  // Head-on with the other's front deeper in: not aligned, the other's fault.
  EXPECT_EQ(classify_ego_collision(car(0, 0, 0, 0), car(3.8, 0, M_PI, 10)), EgoCollision::side);
}

TEST(EgoCollision, OverlapsAtTheFirstStepAreNotCollisionsAndBackgroundPairsCountOnce) {
  // Agents 2 and 3 overlap from the start (exempt); 4 runs into 5 at step 1 and stays in contact at step 2.
  const std::vector<StepResult> steps = {
      step(0, {{1, car(0, 0, 0, 0)}, {2, car(0.5, 1.0, 0, 0)}, {4, car(50, 0, 0, 10)}, {5, car(58, 0, 0, 0)},
               {3, car(100, 0, 0, 0)}}),
      step(1, {{1, car(0, 0, 0, 0)}, {2, car(0.5, 1.0, 0, 0)}, {4, car(55, 0, 0, 10)}, {5, car(58, 0, 0, 0)},
               {3, car(100, 0, 0, 0)}}),
      step(2, {{1, car(0, 0, 0, 0)}, {2, car(0.5, 1.0, 0, 0)}, {4, car(55.5, 0, 0, 0)}, {5, car(58, 0, 0, 0)},
               {3, car(100, 0, 0, 0)}})};
  const EgoOutcome o = ego_outcome(steps, 1, true);
  EXPECT_EQ(o.collision, EgoCollision::none);  // agent 2 overlapped the ego from the first step
  EXPECT_TRUE(o.off_road);
  EXPECT_EQ(o.background_agents, 4);
  EXPECT_EQ(o.background_collided, 2);  // 4 and 5
}

TEST(EgoCollision, AnAgentThatLeavesAndTouchesAgainCollidesAgain) {
  const std::vector<StepResult> steps = {step(0, {{1, car(0, 0, 0, 0)}, {2, car(1, 0, 0, 0)}}),
                                         step(1, {{1, car(0, 0, 0, 0)}, {2, car(10, 0, 0, 0)}}),
                                         step(2, {{1, car(0, 0, 0, 0)}, {2, car(-3, 0, 0, 6)}})};
  const EgoOutcome o = ego_outcome(steps, 1, false);
  EXPECT_EQ(o.collision, EgoCollision::rear_end);
  EXPECT_EQ(o.collision_step, 2);
}

Scenario straight_log() {
  // An SDC driving east at 10 m/s for 9 s, 10 Hz; current frame 10; one lane along its path.
  Scenario s;
  s.id = "straight";
  s.current_time_index = 10;
  Track t;
  t.id = 7;
  t.type = ObjectType::vehicle;
  for (int f = 0; f < 91; ++f) {
    ObjectState o;
    o.x = f * 1.0, o.y = 0, o.heading = 0, o.vx = 10, o.vy = 0;
    o.length = 4.5, o.width = 2.0, o.height = 1.5, o.valid = true;
    t.states.push_back(o);
    s.timestamps.push_back(f * 0.1);
  }
  s.tracks.push_back(t);
  s.sdc_track_index = 0;
  MapFeature lane;
  lane.id = 1;
  lane.kind = MapFeatureKind::lane;
  for (int x = -20; x <= 200; x += 10) lane.points.push_back({static_cast<double>(x), 0.0, 0.0});
  s.map_features.push_back(lane);
  return s;
}

TEST(EgoDriver, LogSlowAndFastFollowTheLoggedPathAtTheirSpeeds) {
  const Scenario s = straight_log();
  StepResult now = step(2, {{7, car(10, 0, 0, 10)}});
  auto log = EgoDriver::create(s, EgoPolicy::log);
  ASSERT_TRUE(log.ok()) << log.status();
  auto c = log->next(now, 4);  // frame 20
  ASSERT_TRUE(c);
  EXPECT_DOUBLE_EQ(c->x, 20.0);
  EXPECT_FALSE(c->speed);
  auto slow = EgoDriver::create(s, EgoPolicy::slow);
  c = slow->next(now, 4);  // 10 frames after the current one, warped to 6: frame 16
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->x, 16.0, 1e-9);
  EXPECT_NEAR(*c->speed, 6.0, 1e-9);
  auto fast = EgoDriver::create(s, EgoPolicy::fast);
  c = fast->next(now, 18);  // frame 90, warped to 10 + 1.3 * 80 = 114: 24 frames past the log's end at 10 m/s
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->x, 90.0 + 24.0, 1e-9);
  EXPECT_NEAR(c->y, 0.0, 1e-9);
  EXPECT_NEAR(*c->speed, 13.0, 1e-9);
  // Past the log's end the log ego has no pose (the session keeps its last control).
  EXPECT_FALSE(log->next(now, 19));
}

TEST(EgoDriver, CruiseAcceleratesTowardItsSpeedAndBrakesForAnAgentAhead) {
  const Scenario s = straight_log();
  auto cruise = EgoDriver::create(s, EgoPolicy::cruise);
  ASSERT_TRUE(cruise.ok());
  StepResult free = step(2, {{7, car(10, 0, 0, 4)}});
  auto c = cruise->next(free, 3);
  ASSERT_TRUE(c);
  EXPECT_NEAR(*c->speed, 4 + 1.5 * 0.5, 1e-9);  // 0.5 (8 - 4) = 2 clipped to 1.5 m/s^2
  EXPECT_NEAR(c->heading, 0.0, 1e-9);            // on its lane
  StepResult blocked = step(2, {{7, car(10, 0, 0, 4)}, {8, car(20, 0.5, 0, 0)}});
  c = cruise->next(blocked, 3);
  ASSERT_TRUE(c);
  EXPECT_NEAR(*c->speed, 4 - 4.0 * 0.5, 1e-9);
}

TEST(EgoDriver, AScenarioWithoutAnSdcIsRefused) {
  Scenario s = straight_log();
  s.sdc_track_index = -1;
  auto d = EgoDriver::create(s, EgoPolicy::log);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(std::string(d.status().message()).find("names no SDC"), std::string::npos);
}

TEST(EgoDriver, NamesRoundTrip) {
  for (EgoPolicy p : {EgoPolicy::log, EgoPolicy::slow, EgoPolicy::fast, EgoPolicy::cruise})
    EXPECT_EQ(ego_policy_from_name(ego_policy_name(p)), p);
  EXPECT_FALSE(ego_policy_from_name("reverse"));
}

}  // namespace
}  // namespace ss
