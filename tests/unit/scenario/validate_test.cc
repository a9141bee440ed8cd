#include "engine/scenario/validate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace ss {
namespace {

Scenario small_scenario() {
  Scenario s;
  s.id = "small";
  s.timestamps = {0.0, 0.1, 0.2};
  s.current_time_index = 1;
  Track t;
  t.id = 7;
  t.type = ObjectType::vehicle;
  t.states.resize(3);
  for (auto& st : t.states) st = {1, 2, 0, 4, 2, 1.5, 0, 1, 0, true};
  s.tracks.push_back(t);
  MapFeature lane;
  lane.id = 3;
  lane.points = {{0, 0, 0}, {10, 0, 0}};
  s.map_features.push_back(lane);
  return s;
}

std::string error_of(const Scenario& s) { return std::string(validate_scenario(s, "f.json").message()); }

TEST(Validate, AcceptsAWellFormedScenario) { EXPECT_TRUE(validate_scenario(small_scenario(), "f").ok()); }

TEST(Validate, NamesTheNonFiniteField) {
  Scenario s = small_scenario();
  s.tracks[0].states[2].x = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_of(s), "f.json: tracks[0] (id 7) states[2].center_x is nan");
  s = small_scenario();
  s.tracks[0].states[1].vy = std::numeric_limits<float>::infinity();
  EXPECT_NE(error_of(s).find("states[1].velocity_y is inf"), std::string::npos);
  s.tracks[0].states[1].valid = false;  // invalid states carry no pose: not checked
  EXPECT_TRUE(validate_scenario(s, "f").ok());
  s = small_scenario();
  s.map_features[0].points[1].y = -std::numeric_limits<double>::infinity();
  EXPECT_NE(error_of(s).find("map_features[0] (id 3, lane) point 1 has a non-finite coordinate"), std::string::npos);
}

TEST(Validate, HoldsCoordinatesToTheOneRangeRule) {
  // Once client scenarios with 1e308 positions were accepted while inject and force refused anything beyond 1e7.
  Scenario s = small_scenario();
  s.tracks[0].states[0].x = 1e308;
  EXPECT_NE(error_of(s).find("tracks[0] (id 7) states[0] lies beyond 1e+07 m"), std::string::npos) << error_of(s);
  s = small_scenario();
  s.tracks[0].states[1].heading = 1e30f;  // a float field: finite, far beyond any angle
  EXPECT_NE(error_of(s).find("states[1].heading 1e+30 is beyond +-1000"), std::string::npos) << error_of(s);
  s = small_scenario();
  s.map_features[0].points[0].y = -2e7;
  EXPECT_NE(error_of(s).find("point 0 (0, -2e+07, 0) lies beyond 1e+07 m"), std::string::npos) << error_of(s);
  s = small_scenario();
  s.tracks[0].states[0].x = 9.9e6;  // far from the origin but within the rule
  EXPECT_TRUE(validate_scenario(s, "f").ok());
}

TEST(Validate, RejectsInconsistentStructure) {
  Scenario s = small_scenario();
  s.tracks[0].states.pop_back();
  EXPECT_NE(error_of(s).find("has 2 states for 3 frames"), std::string::npos);
  s = small_scenario();
  s.current_time_index = 3;
  EXPECT_NE(error_of(s).find("current_time_index 3"), std::string::npos);
  s = small_scenario();
  s.sdc_track_index = 1;
  EXPECT_NE(error_of(s).find("sdc_track_index 1 is outside the 1 tracks"), std::string::npos);
  s = small_scenario();
  s.tracks.push_back(s.tracks[0]);
  EXPECT_NE(error_of(s).find("tracks[1] (id 7): id is used by an earlier track"), std::string::npos);
  s = small_scenario();
  s.timestamps.clear();
  for (auto& t : s.tracks) t.states.clear();
  EXPECT_NE(error_of(s).find("timestamps_seconds is empty"), std::string::npos);
  s = small_scenario();
  s.signals.resize(2);
  EXPECT_NE(error_of(s).find("dynamic_map_states has 2 entries for 3 frames"), std::string::npos);
  s = small_scenario();
  s.tracks_to_predict.push_back({4, 1});
  EXPECT_NE(error_of(s).find("tracks_to_predict[0].track_index 4"), std::string::npos);
  s = small_scenario();
  s.tracks[0].states[0].width = -1;
  EXPECT_NE(error_of(s).find("negative box size"), std::string::npos);
}

}  // namespace
}  // namespace ss
