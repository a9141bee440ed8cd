// A hand-written SUMO network as WOMD map features: lanes and their connectivity, lines, edges, a crosswalk, a stop
// sign, signal links; and SUMO's light characters as WOMD signal states.
#include "offline/dataset/sumo_map.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "offline/dataset/sumo_net.h"

namespace ss {
namespace {

// A junction C at x 100..120. Edge "in" runs east (a sidewalk and two lanes), "back" is its opposite direction,
// "out" leaves C eastwards (one-way), "side" comes from the south and must stop. A crossing spans "out" at x = 112.
const char* kNet = R"(<?xml version="1.0" encoding="UTF-8"?>
<!-- hand-written for the test -->
<net version="1.9">
    <edge id=":C_0" function="internal">
        <lane id=":C_0_0" index="0" speed="13.89" length="20.00" shape="100.00,-1.60 120.00,-1.60"/>
    </edge>
    <edge id=":C_1" function="internal">
        <lane id=":C_1_0" index="0" speed="8.00" length="21.00" shape="100.00,-4.80 110.00,-3.00 120.00,-1.60"/>
    </edge>
    <edge id=":C_2" function="internal">
        <lane id=":C_2_0" index="0" speed="6.00" length="12.00" shape="110.00,-10.00 112.00,-3.00 120.00,-1.60"/>
    </edge>
    <edge id=":C_c0" function="crossing" crossingEdges="out">
        <lane id=":C_c0_0" index="0" allow="pedestrian" speed="1.00" length="8.00" width="4.00" shape="112.00,-4.00 112.00,4.00"/>
    </edge>
    <edge id=":C_w0" function="walkingarea">
        <lane id=":C_w0_0" index="0" allow="pedestrian" speed="1.00" length="2.00" width="2.00" shape="100.00,-8.40 100.00,-6.40"/>
    </edge>
    <edge id="back" from="C" to="W" priority="1">
        <lane id="back_0" index="0" speed="13.89" length="100.00" shape="100.00,1.60 0.00,1.60"/>
    </edge>
    <edge id="in" from="W" to="C" priority="1">
        <lane id="in_0" index="0" allow="pedestrian" speed="1.39" length="100.00" width="2.00" shape="0.00,-7.40 100.00,-7.40"/>
        <lane id="in_1" index="1" disallow="pedestrian" speed="13.89" length="100.00" shape="0.00,-4.80 100.00,-4.80"/>
        <lane id="in_2" index="2" disallow="pedestrian" speed="13.89" length="100.00" shape="0.00,-1.60 100.00,-1.60"/>
    </edge>
    <edge id="out" from="C" to="E" priority="1">
        <lane id="out_0" index="0" speed="25.00" length="100.00" shape="120.00,-1.60 220.00,-1.60"/>
    </edge>
    <edge id="side" from="S" to="C" priority="0">
        <lane id="side_0" index="0" allow="bicycle" speed="8.00" length="90.00" shape="110.00,-100.00 110.00,-10.00"/>
    </edge>
    <tlLogic id="C" type="static" programID="0" offset="0">
        <phase duration="30" state="Gr"/>
        <phase duration="30" state="rG"/>
    </tlLogic>
    <junction id="C" type="traffic_light" x="110.00" y="0.00" incLanes="in_1 in_2 side_0" intLanes=":C_0_0 :C_1_0 :C_2_0" shape=""/>
    <junction id="W" type="dead_end" x="0.00" y="0.00" incLanes="back_0" intLanes="" shape=""/>
    <connection from="in" to="out" fromLane="2" toLane="0" via=":C_0_0" tl="C" linkIndex="0" dir="s" state="O"/>
    <connection from="in" to="out" fromLane="1" toLane="0" via=":C_1_0" tl="C" linkIndex="1" dir="l" state="O"/>
    <connection from="side" to="out" fromLane="0" toLane="0" via=":C_2_0" dir="r" state="s"/>
    <connection from=":C_0" to="out" fromLane="0" toLane="0" dir="s" state="M"/>
    <connection from=":C_1" to="out" fromLane="0" toLane="0" dir="l" state="M"/>
    <connection from=":C_2" to="out" fromLane="0" toLane="0" dir="r" state="M"/>
</net>
)";

class SumoMapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto n = parse_sumo_net(kNet, "t.net.xml");
    ASSERT_TRUE(n.ok()) << n.status();
    net_ = std::move(*n);
    map_ = build_sumo_map(net_);
  }
  const MapFeature& lane(const std::string& id) const {
    const int64_t fid = map_.feature_of_lane[net_.find_lane(id)];
    EXPECT_GT(fid, 0) << id;
    return map_.features[fid - 1];
  }
  std::vector<const MapFeature*> of_kind(MapFeatureKind k) const {
    std::vector<const MapFeature*> out;
    for (const MapFeature& f : map_.features)
      if (f.kind == k) out.push_back(&f);
    return out;
  }
  // The line feature whose points all lie on y = `y` between x0 and x1.
  const MapFeature* line_at(MapFeatureKind k, double y, double x0, double x1) const {
    for (const MapFeature* f : of_kind(k)) {
      bool on = f->points.size() >= 2;
      for (const MapPoint& p : f->points) on = on && std::abs(p.y - y) < 1e-6 && p.x >= x0 - 1e-6 && p.x <= x1 + 1e-6;
      if (on) return f;
    }
    return nullptr;
  }
  SumoNet net_;
  SumoMap map_;
};

TEST_F(SumoMapTest, NetworkParses) {
  EXPECT_EQ(net_.lanes.size(), 11u);
  EXPECT_EQ(net_.connections.size(), 6u);
  EXPECT_EQ(net_.traffic_lights, std::vector<std::string>{"C"});
  EXPECT_EQ(net_.lanes[net_.find_lane("in_0")].use, SumoLaneUse::sidewalk);
  EXPECT_EQ(net_.lanes[net_.find_lane("in_1")].use, SumoLaneUse::road);
  EXPECT_EQ(net_.lanes[net_.find_lane("side_0")].use, SumoLaneUse::bike);
  EXPECT_DOUBLE_EQ(net_.lanes[net_.find_lane("in_1")].width, 3.2);  // SUMO's default
}

TEST_F(SumoMapTest, LanesWithConnectivityThroughInternalLanes) {
  EXPECT_EQ(of_kind(MapFeatureKind::lane).size(), 8u);  // not the sidewalk, crossing or walking area
  const MapFeature& in2 = lane("in_2");
  const MapFeature& via = lane(":C_0_0");
  const MapFeature& out = lane("out_0");
  EXPECT_FALSE(in2.lane.interpolating);
  EXPECT_TRUE(via.lane.interpolating);
  EXPECT_EQ(in2.lane.exit_lanes, std::vector<int64_t>{via.id});
  EXPECT_EQ(via.lane.entry_lanes, std::vector<int64_t>{in2.id});
  EXPECT_EQ(via.lane.exit_lanes, std::vector<int64_t>{out.id});
  EXPECT_EQ(out.lane.entry_lanes.size(), 3u);
  EXPECT_EQ(in2.subtype, 2);                 // surface street
  EXPECT_EQ(out.subtype, 1);                 // 90 km/h: freeway
  EXPECT_EQ(lane("side_0").subtype, 3);      // bike lane
  EXPECT_NEAR(in2.lane.speed_limit_mph, 31.07, 0.01);
  // WOMD spacing: 0.5 m, first and last points kept.
  ASSERT_EQ(in2.points.size(), 201u);
  EXPECT_NEAR(in2.points[1].x - in2.points[0].x, 0.5, 1e-9);
  EXPECT_DOUBLE_EQ(in2.points.back().x, 100.0);
}

TEST_F(SumoMapTest, LinesAndEdgesBorderTheCarriageways) {
  const MapFeature& in1 = lane("in_1");
  const MapFeature& in2 = lane("in_2");
  // Between the two lanes of "in": a broken white line, referenced as their neighbour boundary.
  const MapFeature* lane_line = line_at(MapFeatureKind::road_line, -3.2, 0, 100);
  ASSERT_NE(lane_line, nullptr);
  EXPECT_EQ(lane_line->subtype, static_cast<int32_t>(RoadLineType::broken_single_white));
  ASSERT_EQ(in1.lane.left_neighbors.size(), 1u);
  EXPECT_EQ(in1.lane.left_neighbors[0].feature_id, in2.id);
  EXPECT_EQ(in1.lane.left_neighbors[0].boundaries[0].boundary_feature_id, lane_line->id);
  EXPECT_EQ(in2.lane.right_neighbors[0].feature_id, in1.id);
  // The curb on the right of "in" (the sidewalk is not a driven lane), one centre line shared with "back".
  EXPECT_NE(line_at(MapFeatureKind::road_edge, -6.4, 0, 100), nullptr);
  const MapFeature* centre = line_at(MapFeatureKind::road_line, 0.0, 0, 100);
  ASSERT_NE(centre, nullptr);
  EXPECT_EQ(centre->subtype, static_cast<int32_t>(RoadLineType::solid_double_yellow));
  int centre_lines = 0;
  for (const MapFeature* f : of_kind(MapFeatureKind::road_line)) centre_lines += f->subtype == centre->subtype;
  EXPECT_EQ(centre_lines, 1);
  EXPECT_EQ(in2.lane.left_boundaries.back().boundary_feature_id, centre->id);
  EXPECT_EQ(lane("back_0").lane.left_boundaries.back().boundary_feature_id, centre->id);
  // "out" is one-way: curbs on both sides.
  EXPECT_NE(line_at(MapFeatureKind::road_edge, -3.2, 120, 220), nullptr);
  EXPECT_NE(line_at(MapFeatureKind::road_edge, 0.0, 120, 220), nullptr);
}

TEST_F(SumoMapTest, CrossingBecomesACrosswalk) {
  auto walks = of_kind(MapFeatureKind::crosswalk);
  ASSERT_EQ(walks.size(), 1u);
  // The crossing's centre line +- half its 4 m width, not closed (WOMD does not repeat the first point).
  const std::vector<MapPoint> want = {{114, -4, 0}, {114, 4, 0}, {110, 4, 0}, {110, -4, 0}};
  ASSERT_EQ(walks[0]->points.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_NEAR(walks[0]->points[i].x, want[i].x, 1e-9) << i;
    EXPECT_NEAR(walks[0]->points[i].y, want[i].y, 1e-9) << i;
  }
}

TEST_F(SumoMapTest, StopLinkGivesAStopSignAtTheCurb) {
  auto signs = of_kind(MapFeatureKind::stop_sign);
  ASSERT_EQ(signs.size(), 1u);
  EXPECT_EQ(signs[0]->stop_sign_lanes, std::vector<int64_t>{lane("side_0").id});
  ASSERT_EQ(signs[0]->points.size(), 1u);
  EXPECT_NEAR(signs[0]->points[0].x, 111.6, 1e-9);  // northbound lane: its right (east) border at the stop line
  EXPECT_NEAR(signs[0]->points[0].y, -10.0, 1e-9);
}

TEST_F(SumoMapTest, SignalLinksNameTheInternalLaneAndItsStopLine) {
  ASSERT_EQ(map_.signal_links.size(), 2u);
  const SignalLink& straight = map_.signal_links[0];
  EXPECT_EQ(straight.tl, "C");
  EXPECT_EQ(straight.link_index, 0);
  EXPECT_EQ(straight.lane, lane(":C_0_0").id);
  EXPECT_DOUBLE_EQ(straight.stop_point.x, 100.0);
  EXPECT_DOUBLE_EQ(straight.stop_point.y, -1.6);
  EXPECT_EQ(map_.signal_links[1].dir, 'l');
}

TEST(SumoSignals, LightCharactersAsWomdStates) {
  struct Case {
    char state, dir;
    SignalState want;
  };
  const Case cases[] = {
      {'G', 's', SignalState::go},          {'G', 'r', SignalState::go},
      {'G', 'l', SignalState::arrow_go},    {'G', 't', SignalState::arrow_go},     // protected turn
      {'g', 'l', SignalState::go},          {'g', 's', SignalState::go},           // permissive: yield
      {'y', 's', SignalState::caution},     {'y', 'l', SignalState::arrow_caution},
      {'Y', 's', SignalState::caution},     {'r', 's', SignalState::stop},
      {'r', 'l', SignalState::arrow_stop},  {'R', 'r', SignalState::stop},
      {'u', 's', SignalState::stop},        {'s', 'r', SignalState::flashing_stop},
      {'o', 's', SignalState::flashing_caution}, {'O', 's', SignalState::unknown},
      {'?', 's', SignalState::unknown}};
  for (const Case& c : cases)
    EXPECT_EQ(signal_state_from_sumo(c.state, c.dir), c.want) << c.state << " " << c.dir;
}

TEST_F(SumoMapTest, CropsKeepOnlyReferencesInside) {
  EXPECT_TRUE(crop_map(map_, {1000, 1000}, 50).empty());
  // Around the far end of "out": the lane, its curbs; its entry lanes (internal, at the junction) are outside.
  std::vector<MapFeature> crop = crop_map(map_, {215, -1.6}, 10);
  auto it = std::find_if(crop.begin(), crop.end(), [&](const MapFeature& f) { return f.id == lane("out_0").id; });
  ASSERT_NE(it, crop.end());
  EXPECT_TRUE(it->lane.entry_lanes.empty());
  for (const MapFeature& f : crop) EXPECT_NE(f.kind, MapFeatureKind::crosswalk);
  // Around the junction: the internal lanes keep their connections to lanes inside the crop.
  crop = crop_map(map_, {110, -2}, 30);
  it = std::find_if(crop.begin(), crop.end(), [&](const MapFeature& f) { return f.id == lane(":C_0_0").id; });
  ASSERT_NE(it, crop.end());
  EXPECT_EQ(it->lane.exit_lanes, std::vector<int64_t>{lane("out_0").id});
}

TEST_F(SumoMapTest, CropsCutLinesToTheCircle) {
  const std::vector<MapFeature> crop = crop_map(map_, {50, -1.6}, 10);
  auto find = [&](int64_t id) {
    auto it = std::find_if(crop.begin(), crop.end(), [&](const MapFeature& f) { return f.id == id; });
    EXPECT_NE(it, crop.end()) << id;
    return *it;
  };
  // in_2 runs through the centre: x 40..60 is inside, and one point beyond each end reaches the circle.
  const MapFeature in2 = find(lane("in_2").id);
  ASSERT_EQ(in2.points.size(), 43u);
  EXPECT_DOUBLE_EQ(in2.points.front().x, 39.5);
  EXPECT_DOUBLE_EQ(in2.points.back().x, 60.5);
  // in_1, 3.2 m to the side, is inside for |x - 50| <= 9.47: x 41..59, plus one point each side.
  const MapFeature in1 = find(lane("in_1").id);
  ASSERT_EQ(in1.points.size(), 39u);
  EXPECT_DOUBLE_EQ(in1.points.front().x, 40.5);
  // Neighbour and boundary indices follow the cut of each lane.
  ASSERT_EQ(in1.lane.left_neighbors.size(), 1u);
  const LaneNeighbor& n = in1.lane.left_neighbors[0];
  EXPECT_EQ(n.self_start_index, 0);
  EXPECT_EQ(n.self_end_index, 38);
  EXPECT_EQ(n.neighbor_start_index, 0);
  EXPECT_EQ(n.neighbor_end_index, 42);
  EXPECT_EQ(n.boundaries[0].lane_end_index, 38);
  EXPECT_EQ(in1.lane.left_boundaries[0].lane_end_index, 38);
  // Lanes leave the circle: their connections (at x = 0 and 100) are gone.
  EXPECT_TRUE(in2.lane.exit_lanes.empty());
}

TEST(SumoNet, SignalOffsetsAreRewritten) {
  const std::string xml = R"(<net><tlLogic id="a" type="static" programID="0" offset="0"><phase duration="5" state="G"/>
</tlLogic><tlLogic id="b" type="actuated" programID="0"></tlLogic></net>)";
  const std::string out = with_tls_offsets(xml, [](int i) { return 17 + i; });
  EXPECT_NE(out.find(R"(<tlLogic id="a" type="static" programID="0" offset="17">)"), std::string::npos) << out;
  EXPECT_NE(out.find(R"(<tlLogic id="b" type="actuated" programID="0" offset="18">)"), std::string::npos) << out;
  EXPECT_NE(out.find(R"(<phase duration="5" state="G"/>)"), std::string::npos);
}

TEST(SumoNet, BrokenNetworksAreErrorsWithTheirPlace) {
  auto no_net = parse_sumo_net("<routes/>", "x.xml");
  ASSERT_FALSE(no_net.ok());
  EXPECT_NE(no_net.status().message().find("not a SUMO network"), std::string_view::npos);
  auto bad_connection = parse_sumo_net(R"(<net>
<edge id="a" from="A" to="B"><lane id="a_0" index="0" speed="1" length="1" shape="0,0 1,0"/></edge>
<connection from="a" to="nowhere" fromLane="0" toLane="0"/></net>)",
                                       "y.xml");
  ASSERT_FALSE(bad_connection.ok());
  EXPECT_NE(bad_connection.status().message().find("y.xml:3"), std::string_view::npos)
      << bad_connection.status().message();
}

TEST(Polylines, ResampleAndOffset) {
  const std::vector<Vec2> l = {{0, 0}, {1.2, 0}, {1.2, 1.0}};
  const std::vector<Vec2> r = resample_polyline(l, 0.5);
  // 2.2 m long: points at 0, 0.5, 1.0, 1.5 (0.3 up the second leg), 2.0, and the end.
  ASSERT_EQ(r.size(), 6u);
  EXPECT_NEAR(r[3].x, 1.2, 1e-9);
  EXPECT_NEAR(r[3].y, 0.3, 1e-9);
  EXPECT_NEAR(r.back().y, 1.0, 1e-12);
  const std::vector<Vec2> o = offset_polyline({{0, 0}, {10, 0}}, 2.0);
  EXPECT_NEAR(o[0].y, 2.0, 1e-12);  // left of an eastward line is north
  EXPECT_NEAR(o[1].y, 2.0, 1e-12);
  const std::vector<Vec2> corner = offset_polyline({{0, 0}, {10, 0}, {10, 10}}, -1.0);  // right of a left turn
  EXPECT_NEAR(corner[1].x, 11.0, 1e-9);  // the mitre keeps both legs 1 m away
  EXPECT_NEAR(corner[1].y, -1.0, 1e-9);
}

}  // namespace
}  // namespace ss
