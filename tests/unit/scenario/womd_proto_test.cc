#include "engine/scenario/womd_proto.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "engine/scenario/read.h"
#include "engine/scenario/tfrecord.h"
#include "womd/scenario.pb.h"

namespace ss {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;
namespace wo = waymo::open_dataset;

const std::string kDir = std::string(SS_DATA_DIR) + "/womd/tfrecord";
const std::string kOne = kDir + "/motion_data_one_scenario.tfrecord";
const std::string kInput = kDir + "/womd_scenario_input.tfrecord";

std::string msg(const absl::Status& s) { return std::string(s.message()); }

std::string temp_dir(const std::string& name) {
  const fs::path d = fs::path(::testing::TempDir()) / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d.string();
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream b;
  b << in.rdbuf();
  return b.str();
}

std::map<ObjectType, int> tracks_by_type(const Scenario& s) {
  std::map<ObjectType, int> n;
  for (const Track& t : s.tracks) ++n[t.type];
  return n;
}

std::map<MapFeatureKind, int> features_by_kind(const Scenario& s) {
  std::map<MapFeatureKind, int> n;
  for (const MapFeature& f : s.map_features) ++n[f.kind];
  return n;
}

size_t signal_states(const Scenario& s) {
  size_t n = 0;
  for (const auto& frame : s.signals) n += frame.size();
  return n;
}

// ---- the real files: counts from ../shared/data/womd/README.md ----

TEST(WomdRealData, MotionDataOneScenario) {
  auto read = read_scenarios(kOne);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), 1u);
  const Scenario& s = read->front();
  EXPECT_EQ(s.id, "637f20cafde22ff8");
  EXPECT_EQ(s.num_frames(), 91);
  EXPECT_EQ(s.current_time_index, 10);
  EXPECT_EQ(s.tracks.size(), 83u);
  EXPECT_EQ(tracks_by_type(s), (std::map<ObjectType, int>{
                                   {ObjectType::vehicle, 70}, {ObjectType::pedestrian, 10}, {ObjectType::cyclist, 3}}));
  EXPECT_EQ(s.sdc_track_index, 82);
  EXPECT_EQ(s.tracks_to_predict.size(), 3u);
  EXPECT_EQ(s.signals.size(), 91u);
  EXPECT_EQ(signal_states(s), 1092u);
  EXPECT_EQ(s.map_features.size(), 301u);
  EXPECT_EQ(features_by_kind(s), (std::map<MapFeatureKind, int>{{MapFeatureKind::lane, 199},
                                                                {MapFeatureKind::road_line, 59},
                                                                {MapFeatureKind::road_edge, 28},
                                                                {MapFeatureKind::stop_sign, 8},
                                                                {MapFeatureKind::crosswalk, 4},
                                                                {MapFeatureKind::speed_bump, 3}}));
  // Every signal state in this file has a stop point; every stop sign a position.
  for (const auto& frame : s.signals)
    for (const SignalLaneState& ls : frame) EXPECT_TRUE(ls.has_stop_point);
  for (const MapFeature& f : s.map_features) {
    if (f.kind == MapFeatureKind::stop_sign) {
      EXPECT_EQ(f.points.size(), 1u);
    }
  }
}

TEST(WomdRealData, WomdScenarioInput) {
  auto read = read_scenarios(kInput);  // holds the undocumented Scenario field 3: skipped
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), 1u);
  const Scenario& s = read->front();
  EXPECT_EQ(s.id, "ee519cf571686d19");
  EXPECT_EQ(s.num_frames(), 91);
  EXPECT_EQ(s.current_time_index, 10);
  EXPECT_EQ(s.tracks.size(), 257u);
  EXPECT_EQ(tracks_by_type(s),
            (std::map<ObjectType, int>{{ObjectType::vehicle, 189}, {ObjectType::pedestrian, 68}}));
  EXPECT_EQ(s.objects_of_interest, (std::vector<int32_t>{625, 2694}));
  EXPECT_EQ(s.tracks_to_predict.size(), 4u);
  EXPECT_EQ(s.map_features.size(), 215u);
  EXPECT_EQ(signal_states(s), 0u);
  // Not in the README table; checked against the Python protobuf runtime.
  EXPECT_EQ(s.sdc_track_index, 256);
  EXPECT_EQ(features_by_kind(s), (std::map<MapFeatureKind, int>{{MapFeatureKind::lane, 114},
                                                                {MapFeatureKind::road_line, 12},
                                                                {MapFeatureKind::road_edge, 75},
                                                                {MapFeatureKind::stop_sign, 4},
                                                                {MapFeatureKind::crosswalk, 4},
                                                                {MapFeatureKind::speed_bump, 6}}));
}

TEST(WomdRealData, InvalidStatesKeepOnlyZ) {
  auto read = read_scenarios(kInput);
  ASSERT_TRUE(read.ok()) << read.status();
  int sparse = 0;
  for (const Track& t : read->front().tracks)
    for (const ObjectState& st : t.states)
      if (!st.valid && st.x == 0 && st.y == 0 && st.length == 0 && st.vx == 0 && st.z != 0) ++sparse;
  EXPECT_EQ(sparse, 14819);  // every invalid state of this file carries only center_z and valid
  // Written back the same way: only fields 4 and 11.
  ObjectState st;
  st.z = -0.04;
  Scenario s;
  s.timestamps = {0};
  s.tracks.push_back({1, ObjectType::vehicle, {st}});
  wo::Scenario p;
  ASSERT_TRUE(p.ParseFromString(scenario_to_womd_bytes(s)));
  const wo::ObjectState& o = p.tracks(0).states(0);
  EXPECT_TRUE(o.has_center_z() && o.has_valid());
  EXPECT_FALSE(o.has_center_x() || o.has_center_y() || o.has_length() || o.has_heading() || o.has_velocity_x());
}

TEST(WomdRealData, DirectoryReadsBothInNameOrder) {
  auto read = read_scenarios(std::vector<std::string>{kDir});
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), 2u);
  EXPECT_EQ((*read)[0].id, "637f20cafde22ff8");
  EXPECT_EQ((*read)[1].id, "ee519cf571686d19");
}

TEST(WomdRealData, WriteReadRoundTrip) {
  for (const std::string& src : {kOne, kInput}) {
    SCOPED_TRACE(src);
    auto original = read_scenarios(src);
    ASSERT_TRUE(original.ok()) << original.status();
    const std::string dir = temp_dir("womd_round_trip");
    const std::string a = dir + "/a.tfrecord", b = dir + "/b.tfrecord";
    ASSERT_TRUE(write_scenarios_tfrecord(a, *original).ok());
    auto again = read_scenarios(a);
    ASSERT_TRUE(again.ok()) << again.status();
    EXPECT_TRUE(*again == *original);
    ASSERT_TRUE(write_scenarios_tfrecord(b, *again).ok());
    EXPECT_EQ(slurp(a), slurp(b));
  }
}

TEST(WomdRealData, ReencodingReproducesTheOriginalRecord) {
  // This file has no unknown fields, so the writer, which follows the field layout of real files, gives back the
  // very bytes Waymo wrote.
  auto records = read_tfrecord_file(kOne);
  ASSERT_TRUE(records.ok()) << records.status();
  auto s = scenario_from_womd_bytes(records->front(), "one");
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(scenario_to_womd_bytes(*s) == records->front());
}

// ---- small hand-built scenarios ----

// One of everything scenario.h holds, with values that catch field mix-ups.
Scenario small_scenario() {
  Scenario s;
  s.id = "tiny-\xC3\xA9";
  s.timestamps = {0.0, 0.1, 0.2};
  s.current_time_index = 1;
  ObjectState v{1.5, -2.5, 0.25, 4.5f, 2.0f, 1.6f, 0.5f, 3.0f, -1.0f, true};
  ObjectState sparse;  // as in real files: only z
  sparse.z = -0.125;
  ObjectState full_invalid = v;
  full_invalid.valid = false;
  ObjectState neg_zero = v;
  neg_zero.x = -0.0;
  s.tracks.push_back({7, ObjectType::vehicle, {v, sparse, full_invalid}});
  s.tracks.push_back({-3, ObjectType::cyclist, {sparse, neg_zero, v}});

  MapFeature lane;
  lane.id = 100;
  lane.kind = MapFeatureKind::lane;
  lane.subtype = 2;
  lane.points = {{0, 0, 0}, {1, 0, 0.5}, {2, 0.25, 1}};
  lane.lane.speed_limit_mph = 25;
  lane.lane.interpolating = true;
  lane.lane.entry_lanes = {-1, 101};
  lane.lane.exit_lanes = {102};
  lane.lane.left_neighbors.push_back({103, 0, 2, 1, 3, {{0, 2, 200, 5}, {2, 2, 201, 1}}});
  lane.lane.right_neighbors.push_back({104, 1, 2, 0, 1, {}});
  lane.lane.left_boundaries.push_back({0, 1, 200, 7});
  lane.lane.right_boundaries.push_back({1, 2, 202, 0});
  s.map_features.push_back(lane);
  s.map_features.push_back({200, MapFeatureKind::road_line, 5, {{0, 1, 0}, {2, 1, 0}}, {}, {}});
  s.map_features.push_back({201, MapFeatureKind::road_edge, 2, {{0, 2, 0}, {2, 2, 0}}, {}, {}});
  s.map_features.push_back({300, MapFeatureKind::stop_sign, 0, {{3, 3, 0}}, {}, {100, 101}});
  s.map_features.push_back({301, MapFeatureKind::stop_sign, 0, {}, {}, {}});
  s.map_features.push_back({400, MapFeatureKind::crosswalk, 0, {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}}, {}, {}});
  s.map_features.push_back({401, MapFeatureKind::speed_bump, 0, {{5, 5, 0}, {6, 5, 0}, {6, 6, 0}}, {}, {}});
  s.map_features.push_back({402, MapFeatureKind::driveway, 0, {{7, 7, 0}, {8, 7, 0}, {8, 8, 0}}, {}, {}});

  s.signals = {{{100, SignalState::go, {2, 0.25, 1}, true}, {101, SignalState::arrow_caution, {}, false}},
               {},
               {{100, SignalState::flashing_caution, {2, 0.25, 1}, true}}};
  s.sdc_track_index = 0;
  s.objects_of_interest = {7, -3};
  s.tracks_to_predict = {{1, 2}, {0, 0}};
  s.laser_data = {std::string("\x00\xFF\x01", 3), ""};
  s.camera_tokens = {"tokens"};
  return s;
}

TEST(WomdProto, HandBuiltRoundTripIsExact) {
  const Scenario s = small_scenario();
  ASSERT_TRUE(check_womd_representable(s, "tiny").ok());
  const std::string bytes = scenario_to_womd_bytes(s);
  auto back = scenario_from_womd_bytes(bytes, "tiny");
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_TRUE(*back == s);
  EXPECT_TRUE(std::signbit(back->tracks[1].states[1].x));  // -0.0 survives
  EXPECT_EQ(scenario_to_womd_bytes(*back), bytes);

  // The proto side says what the README says it should.
  wo::Scenario p;
  ASSERT_TRUE(p.ParseFromString(bytes));
  EXPECT_FALSE(p.dynamic_map_states(0).lane_states(1).has_stop_point());
  EXPECT_FALSE(p.map_features(4).stop_sign().has_position());
  EXPECT_EQ(p.map_features(3).stop_sign().position().x(), 3);
  EXPECT_EQ(p.tracks(0).states(2).center_x(), 1.5);  // an invalid state with a pose keeps it
}

TEST(WomdProto, NoSdcTrackIsMinusOne) {
  Scenario s = small_scenario();
  s.sdc_track_index = -1;
  const std::string bytes = scenario_to_womd_bytes(s);
  wo::Scenario p;
  ASSERT_TRUE(p.ParseFromString(bytes));
  EXPECT_FALSE(p.has_sdc_track_index());
  auto back = scenario_from_womd_bytes(bytes, "tiny");
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->sdc_track_index, -1);
}

wo::Scenario small_proto() {
  wo::Scenario p;
  p.set_scenario_id("p");
  for (int i = 0; i < 8; ++i) p.add_timestamps_seconds(0.1 * i);
  for (int t = 0; t < 4; ++t) {
    wo::Track* tr = p.add_tracks();
    tr->set_id(10 + t);
    tr->set_object_type(wo::Track::TYPE_VEHICLE);
    for (int i = 0; i < 8; ++i) {
      wo::ObjectState* o = tr->add_states();
      o->set_center_x(i);
      o->set_valid(true);
    }
  }
  return p;
}

TEST(WomdProto, NanCenterXInValidStateNamesTrackAndField) {
  wo::Scenario p = small_proto();
  p.mutable_tracks(3)->mutable_states(7)->set_center_x(std::numeric_limits<double>::quiet_NaN());
  auto s = scenario_from_womd_bytes(p.SerializeAsString(), "x.tfrecord record 2");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(msg(s.status()), HasSubstr("x.tfrecord record 2"));
  EXPECT_THAT(msg(s.status()), HasSubstr("tracks[3]"));
  EXPECT_THAT(msg(s.status()), HasSubstr("states[7].center_x"));
  // In an invalid state the pose means nothing and is kept as it is.
  p.mutable_tracks(3)->mutable_states(7)->set_valid(false);
  EXPECT_TRUE(scenario_from_womd_bytes(p.SerializeAsString(), "x").ok());
}

TEST(WomdProto, UnknownEnumValueNamesTheField) {
  wo::Scenario p = small_proto();
  std::string bytes = p.SerializeAsString();
  // Append a map feature whose road_edge type is 9 (RoadEdgeType stops at 2): the generated setter refuses it.
  wo::Scenario extra;
  extra.add_map_features()->set_id(5);
  extra.mutable_map_features(0)->mutable_road_edge()->mutable_unknown_fields()->AddVarint(1, 9);
  bytes += extra.SerializeAsString();
  auto s = scenario_from_womd_bytes(bytes, "f record 0");
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(msg(s.status()), HasSubstr("f record 0: Scenario.map_features[0].road_edge.type: value 9 is not a "
                                         "known RoadEdge.RoadEdgeType value"));
}

TEST(WomdProto, OutOfRangeEnumsInAScenarioFailOnReadNotOnWrite) {
  Scenario s = small_scenario();
  s.tracks[1].type = static_cast<ObjectType>(11);
  s.map_features[0].lane.left_boundaries[0].boundary_type = -4;
  const std::string bytes = scenario_to_womd_bytes(s);  // must not crash
  auto back = scenario_from_womd_bytes(bytes, "w");
  ASSERT_FALSE(back.ok());
  EXPECT_THAT(msg(back.status()), HasSubstr("Scenario.tracks[1].object_type: value 11 is not a known"));
}

TEST(WomdProto, MapFeatureWithoutDataIsAnError) {
  wo::Scenario p = small_proto();
  p.add_map_features()->set_id(77);
  auto s = scenario_from_womd_bytes(p.SerializeAsString(), "r");
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(msg(s.status()), HasSubstr("Scenario.map_features[0] (id 77): no feature data"));
}

TEST(WomdProto, WireErrorsComeFirst) {
  std::string bytes = small_proto().SerializeAsString();
  bytes += std::string("\x2a\x02\xC3\x28", 4);  // scenario_id (field 5) with invalid UTF-8, last one wins
  auto s = scenario_from_womd_bytes(bytes, "r");
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(msg(s.status()), HasSubstr("Scenario.scenario_id: string is not valid UTF-8"));
}

TEST(WomdProto, UnrepresentableScenariosAreRefusedOnWrite) {
  const std::string dir = temp_dir("womd_unrepresentable");
  Scenario s = small_scenario();
  s.map_features[3].points.push_back({9, 9, 9});
  auto st = write_scenarios_tfrecord(dir + "/x.tfrecord", {s});
  EXPECT_THAT(msg(st), HasSubstr("map_features[3] (id 300, stop_sign): 2 points"));
  s = small_scenario();
  s.signals[0][1].stop_point = {1, 2, 3};
  EXPECT_THAT(msg(check_womd_representable(s, "w")), HasSubstr("dynamic_map_states[0].lane_states[1]"));
  s = small_scenario();
  s.map_features[1].lane.exit_lanes = {5};
  EXPECT_THAT(msg(check_womd_representable(s, "w")), HasSubstr("lane data on a feature that is not a lane"));
  s = small_scenario();
  s.map_features[5].subtype = 1;
  EXPECT_THAT(msg(check_womd_representable(s, "w")), HasSubstr("subtype 1 on a kind that has none"));
  EXPECT_FALSE(fs::exists(dir + "/x.tfrecord"));
}

// ---- read_scenarios / write_scenarios_tfrecord on files and directories ----

TEST(ReadScenarios, MissingPathIsNotFound) {
  auto r = read_scenarios(std::string("/no/such/file.tfrecord"));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(msg(r.status()), HasSubstr("/no/such/file.tfrecord"));
  auto v = read_scenarios(std::vector<std::string>{kOne, "/no/such/dir"});
  EXPECT_EQ(v.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(msg(v.status()), HasSubstr("/no/such/dir"));
}

TEST(ReadScenarios, EmptyFileHoldsNoScenarios) {
  const std::string dir = temp_dir("womd_empty");
  std::ofstream(dir + "/empty.tfrecord").close();
  auto r = read_scenarios(dir + "/empty.tfrecord");
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(msg(r.status()), HasSubstr("empty.tfrecord: holds no scenarios"));
  EXPECT_FALSE(write_scenarios_tfrecord(dir + "/none.tfrecord", {}).ok());
  const std::string empty_dir = temp_dir("womd_empty_dir");
  EXPECT_FALSE(read_scenarios(empty_dir).ok());
}

TEST(ReadScenarios, DirectoryTakesTfrecordFilesInNameOrder) {
  const std::string dir = temp_dir("womd_dir_order");
  Scenario a = small_scenario(), b = small_scenario(), c = small_scenario();
  a.id = "a";
  b.id = "b";
  c.id = "c";
  ASSERT_TRUE(write_scenarios_tfrecord(dir + "/z.tfrecord", {c}).ok());
  ASSERT_TRUE(write_scenarios_tfrecord(dir + "/train.tfrecord-00000-of-00002", {a, b}).ok());
  std::ofstream(dir + "/notes.txt") << "not a scenario";
  fs::create_directories(dir + "/sub.tfrecord");  // a directory: not read
  auto r = read_scenarios(std::vector<std::string>{dir});
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->size(), 3u);
  EXPECT_EQ((*r)[0].id, "a");
  EXPECT_EQ((*r)[1].id, "b");
  EXPECT_EQ((*r)[2].id, "c");
  EXPECT_TRUE((*r)[2] == c);
}

TEST(ListScenarioFiles, SubdirectoriesOnlyWhenRecursive) {
  const std::string dir = temp_dir("list_scenario_files");
  fs::create_directories(dir + "/sub/deeper");
  fs::create_directories(dir + "/dir.tfrecord");  // a directory: never listed itself
  for (const char* f : {"/b.tfrecord-00000-of-00001", "/a.json", "/notes.txt", "/sub/c.json", "/sub/deeper/d.tfrecord"})
    std::ofstream(dir + f) << "x";
  auto top = list_scenario_files(dir, /*recursive=*/false);
  ASSERT_TRUE(top.ok()) << top.status();
  EXPECT_EQ(*top, (std::vector<std::string>{dir + "/a.json", dir + "/b.tfrecord-00000-of-00001"}));
  auto all = list_scenario_files(dir, /*recursive=*/true);
  ASSERT_TRUE(all.ok()) << all.status();
  EXPECT_EQ(*all, (std::vector<std::string>{dir + "/a.json", dir + "/b.tfrecord-00000-of-00001", dir + "/sub/c.json",
                                            dir + "/sub/deeper/d.tfrecord"}));
}

TEST(ListScenarioFiles, FileMissingPathAndEmptyDirectory) {
  const std::string dir = temp_dir("list_scenario_files_edges");
  std::ofstream(dir + "/notes.txt") << "x";
  // A file is itself, whatever its name.
  auto file = list_scenario_files(dir + "/notes.txt", /*recursive=*/false);
  ASSERT_TRUE(file.ok()) << file.status();
  EXPECT_EQ(*file, std::vector<std::string>{dir + "/notes.txt"});
  auto missing = list_scenario_files(dir + "/nope", /*recursive=*/true);
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(msg(missing.status()), HasSubstr("nope: no such file or directory"));
  auto empty = list_scenario_files(dir, /*recursive=*/true);
  EXPECT_EQ(empty.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(msg(empty.status()), HasSubstr(dir + ": holds no *.json or *.tfrecord* files"));
}

TEST(ReadScenarios, BadRecordNamesFileAndIndex) {
  const std::string dir = temp_dir("womd_bad_record");
  wo::Scenario p = small_proto();
  const std::string good = p.SerializeAsString();
  p.mutable_tracks(1)->mutable_states(2)->set_center_y(std::numeric_limits<double>::infinity());
  ASSERT_TRUE(write_tfrecord_file(dir + "/x.tfrecord", {good, good, p.SerializeAsString()}).ok());
  auto r = read_scenarios(dir + "/x.tfrecord");
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(msg(r.status()), HasSubstr("x.tfrecord record 2: tracks[1]"));
  EXPECT_THAT(msg(r.status()), HasSubstr("center_y"));
}

}  // namespace
}  // namespace ss

namespace ss {
namespace {

// The fuzzer's seeds (synthetic, written by hand) must decode, or the fuzzer would start from nothing but errors.
TEST(ReadScenarios, FuzzSeedsDecode) {
  const std::string dir = std::string(SS_SOURCE_DIR) + "/tests/fuzz/corpus/womd_tfrecord_fuzz";
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.starts_with("framing_only")) continue;  // framing without a valid scenario, on purpose
    SCOPED_TRACE(name);
    auto r = read_scenarios(e.path().string());
    EXPECT_TRUE(r.ok()) << r.status();
    ++files;
  }
  EXPECT_GE(files, 3);
}

}  // namespace
}  // namespace ss
