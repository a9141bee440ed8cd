// The viewer's JSON for the page (viewer/convert.h) and its token check (viewer/gateway.h).
#include <gtest/gtest.h>

#include "viewer/convert.h"
#include "viewer/gateway.h"

namespace viewer {
namespace {

pb::Agent* add_agent(pb::Tick* t, int64_t id, double x, double y, bool controlled = false, bool entered = false) {
  pb::Agent* a = t->add_agents();
  a->set_id(id);
  a->set_type(pb::AGENT_TYPE_VEHICLE);
  a->mutable_state()->set_x(x);
  a->mutable_state()->set_y(y);
  a->mutable_state()->set_vx(3);
  a->mutable_state()->set_vy(4);
  a->mutable_state()->set_length(4.5);
  a->mutable_state()->set_width(2);
  a->set_controlled(controlled);
  a->set_entered(entered);
  return a;
}

TEST(ViewerTokenTest, AcceptsBearerCharactersOnly) {
  EXPECT_TRUE(token_ok(""));
  EXPECT_TRUE(token_ok("abc-DEF._~+/=0123456789"));
  EXPECT_FALSE(token_ok("has space"));
  EXPECT_FALSE(token_ok("line\nbreak"));
  EXPECT_FALSE(token_ok("quote\""));
  EXPECT_TRUE(token_ok(std::string(512, 'a')));
  EXPECT_FALSE(token_ok(std::string(513, 'a')));
}

TEST(ViewerConvertTest, TickCarriesRolesEventsAndRoundedNumbers) {
  pb::Tick t;
  t.set_tick(7);
  t.set_step(12);
  add_agent(&t, 1, 10.123456, 20, /*controlled=*/true);
  add_agent(&t, 2, 11, 20.5, false, /*entered=*/true);  // overlaps agent 1
  add_agent(&t, 3, 100, 100);
  t.add_left(9);
  pb::TrafficLight* l = t.add_lights();
  l->set_lane(5);
  l->set_state(pb::LIGHT_STATE_RED);
  l->mutable_stop_point()->set_x(1.23456);
  const ss::EventMap no_map;
  const std::map<int64_t, int> flags = event_flags(no_map, {}, step_result_of(t));
  EXPECT_EQ(flags.at(1), kOverlap);
  EXPECT_EQ(flags.at(2), kOverlap);
  EXPECT_FALSE(flags.contains(3));
  const nlohmann::json j = tick_json(t, flags);
  EXPECT_EQ(j["type"], "tick");
  EXPECT_EQ(j["tick"], 7);
  ASSERT_EQ(j["agents"].size(), 3u);
  EXPECT_EQ(j["agents"][0][0], 1);
  EXPECT_DOUBLE_EQ(j["agents"][0][2].get<double>(), 10.12);  // centimetres
  EXPECT_DOUBLE_EQ(j["agents"][0][7].get<double>(), 5.0);     // speed from (3, 4)
  EXPECT_EQ(j["agents"][0][8], kControlled | kOverlap);
  EXPECT_EQ(j["agents"][1][8], kEntered | kOverlap);
  EXPECT_EQ(j["agents"][2][8], 0);
  EXPECT_EQ(j["left"], nlohmann::json::array({9}));
  EXPECT_EQ(j["lights"][0], nlohmann::json::array({5, 1.23, 0.0, 0.0, 3}));
}

TEST(ViewerConvertTest, ScenarioMarksEntriesOmitsEmptyTracksAndAttachesTheLog) {
  ss::Scenario s;
  s.id = "s";
  s.timestamps = {0, 0.1, 0.2};
  s.current_time_index = 1;
  ss::Track a{.id = 4, .type = ss::ObjectType::pedestrian, .states = {{}, {}, {}}};
  a.states[1] = {.x = 1, .y = 2, .length = 1, .width = 1, .valid = true};
  a.states[2] = {.x = 1.5, .y = 2, .length = 1, .width = 1, .valid = true};
  ss::Track empty{.id = 5, .type = ss::ObjectType::vehicle, .states = {{}, {}, {}}};
  s.tracks = {a, empty};
  s.sdc_track_index = 0;
  s.map_features.push_back({.id = 8, .kind = ss::MapFeatureKind::road_edge, .points = {{0, 0, 0}, {1, 1, 0}}});
  const nlohmann::json j = scenario_json(s, &s);
  EXPECT_EQ(j["sdc"], 4);
  ASSERT_EQ(j["tracks"].size(), 1u);
  EXPECT_EQ(j["tracks"][0]["type"], 1);
  EXPECT_TRUE(j["tracks"][0]["states"][0].is_null());
  EXPECT_EQ(j["tracks"][0]["states"][1][6], kEntered);  // first valid frame after an invalid one
  EXPECT_EQ(j["tracks"][0]["states"][2][6], 0);
  EXPECT_EQ(j["map"][0]["type"], 2);
  EXPECT_EQ(j["map"][0]["pts"], nlohmann::json::array({0.0, 0.0, 1.0, 1.0}));
  EXPECT_EQ(j["log"]["tracks"].size(), 1u);
  EXPECT_TRUE(scenario_json(s, nullptr)["log"].is_null());
}

}  // namespace
}  // namespace viewer
