// Cutting a recorded run into WOMD scenarios, on a synthetic recording: window layout, the ego, validity within the
// radius, dropped windows, signals, determinism.
#include "offline/dataset/windows.h"

#include <gtest/gtest.h>

#include "offline/dataset/sumo_net.h"

namespace ss {
namespace {

const char* kNet = R"(<net version="1.9">
    <edge id=":C_0" function="internal">
        <lane id=":C_0_0" index="0" speed="13.89" length="20.00" shape="100.00,-1.60 120.00,-1.60"/>
    </edge>
    <edge id=":C_1" function="internal">
        <lane id=":C_1_0" index="0" speed="8.00" length="20.00" shape="100.00,-4.80 120.00,-1.60"/>
    </edge>
    <edge id="in" from="W" to="C">
        <lane id="in_0" index="0" speed="13.89" length="100.00" shape="0.00,-4.80 100.00,-4.80"/>
        <lane id="in_1" index="1" speed="13.89" length="100.00" shape="0.00,-1.60 100.00,-1.60"/>
    </edge>
    <edge id="out" from="C" to="E">
        <lane id="out_0" index="0" speed="13.89" length="100.00" shape="120.00,-1.60 220.00,-1.60"/>
    </edge>
    <connection from="in" to="out" fromLane="1" toLane="0" via=":C_0_0" tl="C" linkIndex="0" dir="s" state="O"/>
    <connection from="in" to="out" fromLane="0" toLane="0" via=":C_1_0" tl="C" linkIndex="1" dir="l" state="O"/>
</net>
)";

FcdTrack track(const std::string& id, ObjectType type, int first, int n, Vec2 start, Vec2 per_frame) {
  FcdTrack t;
  t.id = id;
  t.kind = {type, type == ObjectType::pedestrian ? 0.8f : 4.5f, type == ObjectType::pedestrian ? 0.6f : 2.0f, 1.6f};
  t.first_frame = first;
  const float speed = static_cast<float>(norm(per_frame) / 0.1);
  const float heading = speed > 0 ? static_cast<float>(std::atan2(per_frame.y, per_frame.x)) : 0.0f;
  for (int k = 0; k < n; ++k)
    t.states.push_back({start.x + k * per_frame.x, start.y + k * per_frame.y, heading, speed, true});
  return t;
}

class WindowsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto net = parse_sumo_net(kNet, "w.net.xml");
    ASSERT_TRUE(net.ok()) << net.status();
    map_ = build_sumo_map(*net);
    fcd_.begin = 300;
    fcd_.step = 0.1;
    fcd_.frames = 200;
    // Ordered by id, as parse_fcd gives them.
    fcd_.tracks.push_back(track("p0", ObjectType::pedestrian, 0, 200, {100, 58.4}, {0, 0}));     // standing, 60 m beside the road
    fcd_.tracks.push_back(track("v0", ObjectType::vehicle, 0, 200, {0, -1.6}, {1.0, 0}));        // 10 m/s east
    fcd_.tracks.push_back(track("v1", ObjectType::vehicle, 0, 200, {-20, -1.6}, {1.0, 0}));      // 20 m behind
    fcd_.tracks.push_back(track("v2", ObjectType::vehicle, 0, 200, {5000, 0}, {1.0, 0}));        // far away
    signals_.add("C", 0.0, "rG");
    options_.egos_per_window = 4;
  }
  SumoMap map_;
  FcdRecording fcd_;
  SignalTimeline signals_;
  WindowOptions options_;
};

TEST_F(WindowsTest, ScenariosAroundAMovingEgo) {
  WindowCut cut = cut_windows(map_, fcd_, signals_, {}, options_, 7, "t");
  EXPECT_EQ(cut.windows, 3);  // starts at frames 0, 50, 100; 150 + 91 > 200
  // v0 and v1 are 20 m apart: one ego per window (egos are >= 100 m apart); v2 is an ego of its own, alone.
  ASSERT_EQ(cut.scenarios.size(), 6u);
  for (const Scenario& s : cut.scenarios) {
    EXPECT_EQ(s.num_frames(), 91);
    EXPECT_EQ(s.current_time_index, 10);
    EXPECT_DOUBLE_EQ(s.timestamps[0], 0.0);
    EXPECT_DOUBLE_EQ(s.timestamps[90], 9.0);
    ASSERT_EQ(s.sdc_track_index, 0);
    for (const ObjectState& st : s.tracks[0].states) EXPECT_TRUE(st.valid);
    EXPECT_EQ(s.signals.size(), 91u);
  }
  const Scenario* near = nullptr;
  for (const Scenario& s : cut.scenarios)
    if (s.id.starts_with("t_f0_") && s.tracks[0].id != 3) near = &s;  // window 0, ego v0 or v1
  ASSERT_NE(near, nullptr);
  ASSERT_EQ(near->tracks.size(), 3u);  // both cars and the pedestrian; not v2
  const Track& ped = near->tracks[2];
  EXPECT_EQ(ped.type, ObjectType::pedestrian);
  // Valid only while within 100 m of the ego.
  const bool ego_is_v0 = near->tracks[0].id == 1;
  const int first_in_range = ego_is_v0 ? 20 : 40;  // ego x = frame (v0) or frame - 20 (v1); |100 - x| <= 80
  EXPECT_FALSE(ped.states[first_in_range - 1].valid);
  EXPECT_TRUE(ped.states[first_in_range].valid);
  EXPECT_FLOAT_EQ(ped.states[first_in_range].length, 0.8f);
  // Velocity along the heading.
  EXPECT_FLOAT_EQ(near->tracks[0].states[10].vx, 10.0f);
  EXPECT_FLOAT_EQ(near->tracks[0].states[10].vy, 0.0f);
  // The other car is valid throughout and moving: a track to predict; the pedestrian is not.
  ASSERT_EQ(near->tracks_to_predict.size(), 1u);
  EXPECT_EQ(near->tracks_to_predict[0].track_index, 1);
  // Signals: each controlled lane with its state and stop line, every frame.
  ASSERT_EQ(near->signals[10].size(), 2u);
  EXPECT_EQ(near->signals[10][0].state, SignalState::stop);      // 'r', straight
  EXPECT_EQ(near->signals[10][1].state, SignalState::arrow_go);  // 'G', left turn
  EXPECT_DOUBLE_EQ(near->signals[10][0].stop_point.x, 100.0);
  EXPECT_FALSE(near->map_features.empty());
}

TEST_F(WindowsTest, WindowsWithCollisionsOrTeleportsAreDropped) {
  // v1 collides at 312 s (frame 120: windows 1 and 2); v2 teleports at 301 s (window 0, alone).
  const std::vector<Incident> incidents = {{"v1", 312.0, false}, {"v2", 301.0, true}};
  WindowCut cut = cut_windows(map_, fcd_, signals_, incidents, options_, 7, "t");
  EXPECT_EQ(cut.dropped_collision, 2);
  // v2 is not an ego in window 0 (egos must have no incident), so nothing is dropped for its teleport.
  EXPECT_EQ(cut.dropped_teleport, 0);
  ASSERT_EQ(cut.scenarios.size(), 3u);
  for (const Scenario& s : cut.scenarios) {
    if (s.id.starts_with("t_f0_")) {
      EXPECT_NE(s.tracks[0].id, 3);
    }
  }
}

TEST_F(WindowsTest, JumpsAndWhipTurnsAreImplausible) {
  fcd_.tracks[2].states[60].x += 30;  // v1 jumps 30 m out and back: frames 60 and 61, in windows 0 and 1
  WindowCut cut = cut_windows(map_, fcd_, signals_, {}, options_, 7, "t");
  EXPECT_EQ(cut.dropped_implausible, 2);
  EXPECT_EQ(cut.dropped_teleport + cut.dropped_collision, 0);
  // At 10 m/s, turning 0.5 rad in 0.1 s is 50 m/s^2 sideways: not a car. (A pedestrian may turn on the spot.)
  fcd_.tracks.clear();
  SetUp();
  fcd_.tracks[2].states[150].heading += 0.5f;
  fcd_.tracks[0].states[150].heading += 3.0f;
  cut = cut_windows(map_, fcd_, signals_, {}, options_, 7, "t");
  EXPECT_EQ(cut.dropped_implausible, 1);  // window 2 (frames 100..190)
}

TEST_F(WindowsTest, DeterministicForASeed) {
  options_.ego_separation = 10;  // both v0 and v1 can be egos: the seed decides the order
  const WindowCut a = cut_windows(map_, fcd_, signals_, {}, options_, 11, "t");
  const WindowCut b = cut_windows(map_, fcd_, signals_, {}, options_, 11, "t");
  ASSERT_EQ(a.scenarios.size(), b.scenarios.size());
  for (size_t i = 0; i < a.scenarios.size(); ++i) EXPECT_TRUE(a.scenarios[i] == b.scenarios[i]) << i;
}

}  // namespace
}  // namespace ss
