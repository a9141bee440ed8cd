#include "engine/sim/events.h"

#include <gtest/gtest.h>

#include <cmath>

#include "engine/scenario/read.h"

namespace ss {
namespace {

// A straight two-lane road along x: lane 10 eastbound on y = 0, lane 11 westbound on y = 4, road edges at y = -2
// and y = 6 (each with the road on its left).
Scenario road() {
  Scenario s;
  auto feature = [&](int64_t id, MapFeatureKind kind, std::vector<MapPoint> points) {
    MapFeature f;
    f.id = id;
    f.kind = kind;
    f.points = std::move(points);
    s.map_features.push_back(f);
  };
  feature(10, MapFeatureKind::lane, {{0, 0, 5}, {50, 0, 5}, {100, 0, 5}});
  feature(11, MapFeatureKind::lane, {{100, 4, 5}, {0, 4, 5}});
  feature(20, MapFeatureKind::road_edge, {{0, -2, 5}, {100, -2, 5}});
  feature(21, MapFeatureKind::road_edge, {{100, 6, 5}, {0, 6, 5}});
  return s;
}

AgentView agent(int64_t id, double x, double y, double heading, bool controlled) {
  AgentView a;
  a.id = id;
  a.controlled = controlled;
  a.state.x = x;
  a.state.y = y;
  a.state.heading = heading;
  a.state.length = 4.5;
  a.state.width = 2.0;
  a.state.valid = true;
  return a;
}

StepResult tick(std::vector<AgentView> agents, std::vector<LightView> lights = {}) {
  StepResult r;
  r.agents = std::move(agents);
  r.lights = std::move(lights);
  return r;
}

LightView light(int64_t lane, LightState state, double x, double y, double heading) {
  LightView l;
  l.lane = lane;
  l.state = state;
  l.stop_point = {x, y, heading};
  return l;
}

TEST(EventsTest, LanePositionFollowsTheHeading) {
  const EventMap m = event_map_from_scenario(road());
  ASSERT_EQ(m.lanes.size(), 2u);
  EXPECT_DOUBLE_EQ(m.lanes[0].s.back(), 100.0);
  const LanePosition east = lane_position(m, {30, 0.5, 0.1});
  EXPECT_EQ(east.lane_id, 10);
  EXPECT_NEAR(east.s, 30, 1e-12);
  EXPECT_NEAR(east.offset, 0.5, 1e-12);
  EXPECT_NEAR(east.heading_error, 0.1, 1e-12);
  // Facing west at the same point: the westbound lane, 3.5 m to its left, 70 m from its start.
  const LanePosition west = lane_position(m, {30, 0.5, kPi});
  EXPECT_EQ(west.lane_id, 11);
  EXPECT_NEAR(west.s, 70, 1e-12);
  EXPECT_NEAR(west.offset, 3.5, 1e-12);
  EXPECT_EQ(lane_position(m, {30, 20, 0}).lane_id, -1);         // far from every lane
  EXPECT_EQ(lane_position(m, {30, 0.5, kPi / 2 + 0.1}).lane_id, 11);  // across lane 10: only 11 is within 90 degrees
}

TEST(EventsTest, OverlapNamesTheOtherAgents) {
  const EventMap m = event_map_from_scenario(road());
  const StepResult t = tick({agent(1, 30, 0, 0, true), agent(7, 33, 0.5, 0.3, false), agent(5, 40, 0, 0, false),
                             agent(3, 30, 1.5, 0, false)});
  const auto e = tick_events(m, t, t);
  ASSERT_EQ(e.size(), 1u);  // controlled agents only
  EXPECT_EQ(e[0].agent_id, 1);
  EXPECT_EQ(e[0].overlapping, (std::vector<int64_t>{3, 7}));
  // Two controlled agents each see the other.
  const StepResult two = tick({agent(1, 30, 0, 0, true), agent(2, 32, 0, 0, true)});
  const auto e2 = tick_events(m, two, two);
  ASSERT_EQ(e2.size(), 2u);
  EXPECT_EQ(e2[0].overlapping, (std::vector<int64_t>{2}));
  EXPECT_EQ(e2[1].overlapping, (std::vector<int64_t>{1}));
}

TEST(EventsTest, OffRoadByTheMostOffRoadCorner) {
  const EventMap m = event_map_from_scenario(road());
  auto at = [&](double y, double heading) {
    const StepResult t = tick({agent(1, 30, y, heading, true)});
    return tick_events(m, t, t)[0];
  };
  const AgentEvents inside = at(0, 0);  // corners at y = -1: 1 m inside the edge at y = -2
  EXPECT_FALSE(inside.off_road);
  EXPECT_NEAR(inside.road_edge_distance, -1, 1e-9);
  const AgentEvents over = at(-1.5, 0);  // corners at y = -2.5
  EXPECT_TRUE(over.off_road);
  EXPECT_NEAR(over.road_edge_distance, 0.5, 1e-9);
  EXPECT_TRUE(at(0, kPi / 2).off_road);  // turned across the road: its front corners (y = 2.25) are in, rear out
  EXPECT_TRUE(at(10, 0).off_road);       // beyond the far edge
  // No road edges: unknown, not "on the road".
  Scenario bare = road();
  std::erase_if(bare.map_features, [](const MapFeature& f) { return f.kind == MapFeatureKind::road_edge; });
  const StepResult t = tick({agent(1, 30, -5, 0, true)});
  const AgentEvents none = tick_events(event_map_from_scenario(bare), t, t)[0];
  EXPECT_TRUE(std::isnan(none.road_edge_distance));
  EXPECT_FALSE(none.off_road);
}

TEST(EventsTest, RedLightOnlyWhenCrossingItsStopLineWhileRed) {
  const EventMap m = event_map_from_scenario(road());
  auto ran = [&](double x0, double y0, double x1, double y1, LightState state) {
    const StepResult before = tick({agent(1, x0, y0, 0, true)}, {light(10, state, 50, 0, 0)});
    const StepResult after = tick({agent(1, x1, y1, 0, true)}, {light(10, state, 50, 0, 0)});
    const AgentEvents e = tick_events(m, before, after)[0];
    EXPECT_EQ(e.red_light_lane, e.ran_red_light ? 10 : -1);
    return e.ran_red_light;
  };
  EXPECT_TRUE(ran(48, 0, 51, 0, LightState::red));
  EXPECT_TRUE(ran(45, 0, 50, 0, LightState::red));       // reaching the line counts
  EXPECT_TRUE(ran(48, 0, 52, 3, LightState::red));       // crosses at y = 1.5: within the line
  EXPECT_FALSE(ran(48, 0, 51, 0, LightState::green));
  EXPECT_FALSE(ran(48, 0, 51, 0, LightState::yellow));
  EXPECT_FALSE(ran(45, 0, 49.9, 0, LightState::red));    // stopped short
  EXPECT_FALSE(ran(51, 0, 55, 0, LightState::red));      // already past
  EXPECT_FALSE(ran(51, 0, 48, 0, LightState::red));      // backwards
  EXPECT_FALSE(ran(48, 4, 51, 4, LightState::red));      // the next lane over: beyond the line's 2 m
  // An agent that just entered has no previous position: no crossing, no progress.
  const StepResult before = tick({}, {light(10, LightState::red, 50, 0, 0)});
  const StepResult after = tick({agent(1, 51, 0, 0, true)}, {light(10, LightState::red, 50, 0, 0)});
  const AgentEvents e = tick_events(m, before, after)[0];
  EXPECT_FALSE(e.ran_red_light);
  EXPECT_EQ(e.progress, 0);
}

TEST(EventsTest, ProgressAlongTheLane) {
  const EventMap m = event_map_from_scenario(road());
  auto progress = [&](double x0, double y0, double x1, double y1, double heading) {
    const StepResult before = tick({agent(1, x0, y0, heading, true)});
    const StepResult after = tick({agent(1, x1, y1, heading, true)});
    return tick_events(m, before, after)[0].progress;
  };
  EXPECT_NEAR(progress(30, 0, 35, 1, 0), 5, 1e-12);     // sideways motion does not count
  EXPECT_NEAR(progress(35, 0, 30, 0, 0), -5, 1e-12);    // reversing counts against
  EXPECT_NEAR(progress(30, 4, 20, 4, kPi), 10, 1e-12);  // westbound lane
  EXPECT_EQ(progress(30, 20, 40, 20, 0), 0);            // on no lane
  EXPECT_NEAR(progress(30, 2, 40, 20, 0), 10, 1e-12);   // left the lanes: the old lane's direction
}

// On a real WOMD scenario: the SDC at its current frame is on a lane in its heading's direction and on the road.
TEST(EventsTest, RealScenarioSdcIsOnALane) {
  auto all = read_scenarios({std::string(SS_DATA_DIR) + "/womd/tfrecord"});
  ASSERT_TRUE(all.ok()) << all.status();
  ASSERT_FALSE(all->empty());
  for (const Scenario& s : *all) {
    ASSERT_GE(s.sdc_track_index, 0);
    const ObjectState& o = s.tracks[s.sdc_track_index].states[s.current_time_index];
    ASSERT_TRUE(o.valid);
    const EventMap m = event_map_from_scenario(s);
    const LanePosition p = lane_position(m, {o.x, o.y, o.heading});
    EXPECT_GE(p.lane_id, 0) << s.id;
    EXPECT_LT(std::abs(p.offset), 2.0) << s.id;
    StepResult t;
    t.agents.push_back(agent(1, o.x, o.y, o.heading, true));
    t.agents[0].state.length = o.length;
    t.agents[0].state.width = o.width;
    EXPECT_FALSE(tick_events(m, t, t)[0].off_road) << s.id;
  }
}

}  // namespace
}  // namespace ss
