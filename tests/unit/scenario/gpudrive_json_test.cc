#include "engine/scenario/gpudrive_json.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/geometry/geometry.h"

namespace ss {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

const std::string kWomd = std::string(SS_DATA_DIR) + "/womd";

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// ---------------------------------------------------------------------------------------------------------------
// The real files: ../shared/data/womd/README.md is the reference. Its table lists every file with its counts; its
// text states the totals (scenarios per split, files with lights, files without ids) and the worst per-file heading
// agreement. The tests read both and hold the data to them, so when the data changes only the README changes.

struct ReadmeRow {
  std::string file;  // relative to womd/, e.g. json/train/womd_03af226c.json
  size_t objects = 0, roads = 0;
  bool lights = false;
};

// The README's table is the reference for what each file holds; parsing it keeps the test and the README in step.
std::vector<ReadmeRow> readme_rows() {
  std::vector<ReadmeRow> rows;
  std::istringstream in(slurp(kWomd + "/README.md"));
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("| json/", 0) != 0) continue;
    std::vector<std::string> cells;
    std::istringstream cs(line.substr(1));
    for (std::string c; std::getline(cs, c, '|');) {
      c.erase(0, c.find_first_not_of(' '));
      c.erase(c.find_last_not_of(' ') + 1);
      cells.push_back(c);
    }
    if (cells.size() < 4) continue;
    rows.push_back({cells[0], std::stoul(cells[1]), std::stoul(cells[2]), cells[3] == "yes"});
  }
  return rows;
}

// The numbers a sentence of the README states: the groups of `pattern` (line breaks in the README read as spaces).
// Empty, with a failure naming the pattern, when the README no longer says it: reword the pattern with the README.
std::vector<int> readme_numbers(const std::string& pattern) {
  std::string text = slurp(kWomd + "/README.md");
  std::replace(text.begin(), text.end(), '\n', ' ');
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(pattern))) {
    ADD_FAILURE() << "the README no longer says /" << pattern << "/";
    return {};
  }
  std::vector<int> numbers;
  for (size_t i = 1; i < m.size(); ++i) numbers.push_back(std::stoi(m[i].str()));
  return numbers;
}

TEST(GpudriveJsonReal, ReadmeListsEveryFile) {
  const auto rows = readme_rows();
  std::vector<std::string> on_disk, listed;
  for (const char* split : {"train", "val"})
    for (const auto& e : fs::directory_iterator(kWomd + "/json/" + split))
      if (e.path().extension() == ".json")
        on_disk.push_back(std::string("json/") + split + "/" + e.path().filename().string());
  for (const auto& r : rows) listed.push_back(r.file);
  std::sort(on_disk.begin(), on_disk.end());
  std::sort(listed.begin(), listed.end());
  EXPECT_EQ(on_disk, listed);

  // The totals the README's text states are the table's.
  const auto in_split = [&](const std::string& split) {
    return static_cast<int>(std::count_if(rows.begin(), rows.end(), [&](const ReadmeRow& r) {
      return r.file.rfind("json/" + split + "/", 0) == 0;
    }));
  };
  const int light_files =
      static_cast<int>(std::count_if(rows.begin(), rows.end(), [](const ReadmeRow& r) { return r.lights; }));
  const int total = static_cast<int>(rows.size());
  EXPECT_EQ(readme_numbers(R"((\d+) distinct real scenarios \((\d+) in train/, (\d+) in val/\))"),
            (std::vector<int>{total, in_split("train"), in_split("val")}));
  EXPECT_EQ(readme_numbers(R"(only (\d+) of the (\d+) files have lights)"), (std::vector<int>{light_files, total}));
  // Sanity: the data is not a handful of files, and both splits and some lights are there.
  EXPECT_GE(total, 200);
  EXPECT_GE(in_split("val"), 30);
  EXPECT_GT(light_files, 0);
}

// Reads every real file (227, 300 MB, when this was written) twice: with the reader, and with nlohmann for the raw
// headings and geometry sizes. Cost on this 2-core machine: 17 s of CPU (9 s the reader, 8 s the second parse); 26 s
// wall with one other build sharing the cores, 85 s at a load of 9. It grows with the data (ctest's timeout: 300 s).
TEST(GpudriveJsonReal, AllFilesLoadWithTheReadmeCounts) {
  const std::vector<ReadmeRow> rows = readme_rows();
  // The README's worst per-file heading agreement, in %, and its count of files without ids (headings in degrees).
  const std::vector<int> worst = readme_numbers(R"(is (\d+) % at worst)");
  const std::vector<int> no_ids = readme_numbers(R"(Nocturne-style files, (\d+) of these (\d+)\))");
  ASSERT_EQ(worst.size(), 1u);
  ASSERT_EQ(no_ids.size(), 2u);
  EXPECT_EQ(no_ids[1], static_cast<int>(rows.size()));

  int64_t moving = 0, agreeing = 0, other_agreeing = 0;
  int no_id_files = 0, files_with_movers = 0, tied_files = 0;
  double worst_agreement = 1;
  std::string worst_file;
  std::set<std::string> ids;
  std::set<std::vector<std::pair<int64_t, int64_t>>> current_positions;
  for (const ReadmeRow& row : rows) {
    SCOPED_TRACE(row.file);
    const std::string text = slurp(kWomd + "/" + row.file);
    ASSERT_FALSE(text.empty());
    auto s = scenario_from_gpudrive_json(text, row.file);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(s->tracks.size(), row.objects);
    EXPECT_EQ(s->map_features.size(), row.roads);
    EXPECT_EQ(!s->signals.empty(), row.lights);
    EXPECT_EQ(s->num_frames(), 91);
    EXPECT_EQ(s->current_time_index, 10);
    EXPECT_DOUBLE_EQ(s->timestamps[90], 9.0);
    if (!s->signals.empty()) {
      EXPECT_EQ(s->signals.size(), 91u);
    }
    EXPECT_FALSE(s->id.empty());
    EXPECT_EQ(s->id.find(".json"), std::string::npos);

    // Distinct scenarios, as the README says: no two files share a scenario id, nor the positions (to 0.1 m) of the
    // agents valid at the current step (how the duplicates were found).
    EXPECT_TRUE(ids.insert(s->id).second) << "scenario id " << s->id << " twice";
    std::vector<std::pair<int64_t, int64_t>> now;
    for (const Track& t : s->tracks)
      if (const ObjectState& st = t.states[s->current_time_index]; st.valid)
        now.emplace_back(std::llround(st.x * 10), std::llround(st.y * 10));
    std::sort(now.begin(), now.end());
    EXPECT_TRUE(current_positions.insert(now).second) << "the same agents as another file at the current step";

    // The heading unit rule (degrees without ids, radians with) must make headings follow the direction of motion
    // of moving agents. Over all files that holds for 98.9 % of the steps. Per file it is weaker (the README gives
    // the worst; 76.4 % in womd_373e3172, 79.4 % in womd_03d7ef40): pedestrians' velocities are noisy and vehicles
    // reverse. What tells the units apart is that the rule's unit agrees more often than the other unit. In a file
    // whose movers all head east the two units agree equally (a heading near 0 is near 0 in degrees and radians:
    // womd_860064be, womd_96311384), so a tie is allowed only there.
    const json doc = json::parse(text);
    const bool has_ids = doc["objects"][0].contains("id");
    no_id_files += !has_ids;
    int64_t file_moving = 0, file_agreeing = 0, file_other_unit = 0, file_eastward = 0;
    for (size_t i = 0; i < s->tracks.size(); ++i) {
      const Track& t = s->tracks[i];
      for (size_t f = 0; f < t.states.size(); ++f) {
        const ObjectState& st = t.states[f];
        if (!st.valid) continue;
        EXPECT_GE(st.heading, -static_cast<float>(kPi));
        EXPECT_LT(st.heading, static_cast<float>(kPi));
        EXPECT_GT(st.height, 0);
        if (std::hypot(st.vx, st.vy) <= 2.0) continue;
        const double motion = std::atan2(st.vy, st.vx);
        ++file_moving;
        file_agreeing += std::abs(wrap_angle(st.heading - motion)) < 0.5;
        file_eastward += std::abs(motion) < 0.5;
        const double raw = doc["objects"][i]["heading"][f].get<double>();
        const double other = has_ids ? raw * kPi / 180 : raw;
        file_other_unit += std::abs(wrap_angle(other - motion)) < 0.5;
      }
    }
    // (The README says two files have no fast mover; at 2 m/s every file has some, the fewest 55 steps.)
    EXPECT_GT(file_moving, 0);
    if (file_moving > 0) {
      ++files_with_movers;
      const double agreement = static_cast<double>(file_agreeing) / file_moving;
      EXPECT_GE(100 * agreement, worst[0]) << file_agreeing << "/" << file_moving;
      if (agreement < worst_agreement) worst_agreement = agreement, worst_file = row.file;
      EXPECT_GE(file_agreeing, file_other_unit);
      if (file_agreeing == file_other_unit) {
        ++tied_files;
        EXPECT_GE(file_eastward, 0.9 * file_moving) << "the units tie (" << file_agreeing << " of " << file_moving
                                                    << ") but only " << file_eastward << " moving steps head east";
      }
    }
    moving += file_moving;
    agreeing += file_agreeing;
    other_agreeing += file_other_unit;

    // Polygons are never closed in these files, so nothing was dropped: the geometry sizes match the JSON.
    for (size_t i = 0; i < s->map_features.size(); ++i)
      ASSERT_EQ(s->map_features[i].points.size(), doc["roads"][i]["geometry"].size()) << "road " << i;
  }
  EXPECT_EQ(no_id_files, no_ids[0]);
  EXPECT_EQ(files_with_movers, static_cast<int>(rows.size()));
  // The README's worst agreement is the worst file's, rounded down to a whole percent.
  EXPECT_EQ(static_cast<int>(std::floor(100 * worst_agreement)), worst[0]) << worst_file;
  std::printf("heading agrees with motion (speed > 2 m/s, |diff| < 0.5 rad): %lld of %lld steps (%.3f%%); "
              "the other unit %.3f%%; worst file %s %.1f%%; %d files where the units tie\n",
              static_cast<long long>(agreeing), static_cast<long long>(moving), 100.0 * agreeing / moving,
              100.0 * other_agreeing / moving, worst_file.c_str(), 100 * worst_agreement, tied_files);
  EXPECT_GE(agreeing, 0.95 * moving);
  EXPECT_LT(other_agreeing, 0.5 * moving);
}

TEST(GpudriveJsonReal, ReadsMetadataLightsAndSubtypes) {
  // A GPUDrive file with ids, heights and metadata.
  const std::string f1 = "json/train/womd_6524ab33.json";
  auto s = scenario_from_gpudrive_json(slurp(kWomd + "/" + f1), f1);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->id, "db4edc9bd0c9d18c");
  EXPECT_EQ(s->sdc_track_index, 80);
  EXPECT_EQ(s->objects_of_interest, (std::vector<int32_t>{18, 284}));
  ASSERT_FALSE(s->tracks_to_predict.empty());
  EXPECT_EQ(s->tracks_to_predict[0].track_index, 16);

  // An older Nocturne file: no scenario_id, no ids, no heights.
  const std::string f2 = "json/train/womd_0c57196f.json";
  s = scenario_from_gpudrive_json(slurp(kWomd + "/" + f2), f2);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->id, "tfrecord-00105-of-01000_378");
  EXPECT_EQ(s->sdc_track_index, -1);
  for (size_t i = 0; i < s->tracks.size(); ++i) EXPECT_EQ(s->tracks[i].id, static_cast<int32_t>(i));

  // Lights: every one of the 9 lanes of 03af226c is present at all 91 frames; lane 118 is stop throughout.
  const std::string f3 = "json/train/womd_03af226c.json";
  s = scenario_from_gpudrive_json(slurp(kWomd + "/" + f3), f3);
  ASSERT_TRUE(s.ok()) << s.status();
  for (const auto& frame : s->signals) {
    ASSERT_EQ(frame.size(), 9u);
    EXPECT_EQ(frame[0].lane, 118);
    EXPECT_EQ(frame[0].state, SignalState::stop);
    EXPECT_TRUE(frame[0].has_stop_point);
    EXPECT_NEAR(frame[0].stop_point.x, 3013.815676283042, 1e-9);
    EXPECT_TRUE(std::is_sorted(frame.begin(), frame.end(), [](auto& a, auto& b) { return a.lane < b.lane; }));
  }
  // Its roads carry map_element_id: road 0 is a road edge of type 15 = boundary.
  EXPECT_EQ(s->map_features[0].kind, MapFeatureKind::road_edge);
  EXPECT_EQ(s->map_features[0].subtype, 1);
  EXPECT_EQ(s->map_features[0].id, 2);

  // Lanes that appear part-way: 3628df17 has lanes 84, 91 and 92 only from frame 80 on.
  const std::string f4 = "json/train/womd_3628df17.json";
  s = scenario_from_gpudrive_json(slurp(kWomd + "/" + f4), f4);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->signals[79].size(), 13u);
  EXPECT_EQ(s->signals[80].size(), 16u);
}

// ---------------------------------------------------------------------------------------------------------------
// Hand-written documents

constexpr int kFrames = 11;

// A minimal Nocturne-style document: two objects without ids or heights (headings in degrees), one lane.
json small_doc() {
  json doc;
  doc["name"] = "tfrecord-00001-of-01000_7.json";
  json objects = json::array();
  for (int i = 0; i < 2; ++i) {
    json o;
    o["type"] = i == 0 ? "vehicle" : "pedestrian";
    o["length"] = 4.5;
    o["width"] = 2.0;
    o["goalPosition"] = {{"x", 1.0}, {"y", 2.0}};
    o["position"] = json::array();
    o["heading"] = json::array();
    o["velocity"] = json::array();
    o["valid"] = json::array();
    for (int f = 0; f < kFrames; ++f) {
      o["position"].push_back({{"x", 10.0 * i + f}, {"y", 1.0}, {"z", 0.5}});
      o["heading"].push_back(90.0);
      o["velocity"].push_back({{"x", 0.0}, {"y", 5.0}});
      o["valid"].push_back(true);
    }
    objects.push_back(o);
  }
  doc["objects"] = objects;
  doc["roads"] = json::array({{{"type", "lane"}, {"geometry", {{{"x", 0.0}, {"y", 0.0}}, {{"x", 10.0}, {"y", 0.0}}}}}});
  doc["tl_states"] = json::object();
  return doc;
}

absl::StatusOr<Scenario> parse(const json& doc) { return scenario_from_gpudrive_json(doc.dump(), "t.json"); }

std::string error_of(std::string_view text) {
  auto s = scenario_from_gpudrive_json(text, "t.json");
  if (s.ok()) return "OK";
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
  return std::string(s.status().message());
}
// EXPECT_ERROR takes a document or raw text; exact-match overloads keep strings from converting to json.
std::string as_text(const json& doc) { return doc.dump(); }
std::string as_text(const std::string& text) { return text; }
std::string as_text(const char* text) { return text; }

#define EXPECT_ERROR(input, fragment)                                                       \
  do {                                                                                      \
    std::string msg_ = error_of(as_text(input));                                               \
    EXPECT_EQ(msg_.rfind("t.json: ", 0), 0u) << msg_;                                       \
    EXPECT_NE(msg_.find(fragment), std::string::npos) << "message: " << msg_;               \
  } while (0)

TEST(GpudriveJson, ReadsANocturneDocument) {
  auto s = parse(small_doc());
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->id, "tfrecord-00001-of-01000_7");
  EXPECT_EQ(s->num_frames(), kFrames);
  EXPECT_DOUBLE_EQ(s->timestamps[3], 0.3);
  EXPECT_EQ(s->current_time_index, 10);
  ASSERT_EQ(s->tracks.size(), 2u);
  EXPECT_EQ(s->tracks[1].id, 1);
  EXPECT_EQ(s->tracks[1].type, ObjectType::pedestrian);
  const ObjectState& st = s->tracks[0].states[4];
  EXPECT_TRUE(st.valid);
  EXPECT_DOUBLE_EQ(st.x, 4.0);
  EXPECT_DOUBLE_EQ(st.z, 0.5);
  EXPECT_FLOAT_EQ(st.heading, static_cast<float>(kPi / 2));  // 90 degrees
  EXPECT_FLOAT_EQ(st.vy, 5.0f);
  EXPECT_FLOAT_EQ(st.length, 4.5f);
  EXPECT_FLOAT_EQ(st.height, 1.65f);                         // vehicle default
  EXPECT_FLOAT_EQ(s->tracks[1].states[0].height, 1.75f);    // pedestrian default
  EXPECT_TRUE(s->signals.empty());
  EXPECT_EQ(s->sdc_track_index, -1);
  ASSERT_EQ(s->map_features.size(), 1u);
  EXPECT_EQ(s->map_features[0].id, 0);
  EXPECT_EQ(s->map_features[0].subtype, 0);
  EXPECT_DOUBLE_EQ(s->map_features[0].points[1].z, 0.0);
}

TEST(GpudriveJson, WrapsDegreeHeadings) {
  json doc = small_doc();
  doc["objects"][0]["heading"][0] = 450.0;
  doc["objects"][0]["heading"][1] = -270.0;
  doc["objects"][0]["heading"][2] = 180.0;
  doc["objects"][0]["heading"][3] = 539.0;
  auto s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_NEAR(s->tracks[0].states[0].heading, kPi / 2, 1e-6);
  EXPECT_NEAR(s->tracks[0].states[1].heading, kPi / 2, 1e-6);
  EXPECT_NEAR(s->tracks[0].states[2].heading, -kPi, 1e-6);  // [-pi, pi)
  EXPECT_NEAR(s->tracks[0].states[3].heading, 179.0 * kPi / 180, 1e-6);
}

TEST(GpudriveJson, ReadsAGpudriveDocumentWithIdsHeightsAndMetadata) {
  json doc = small_doc();
  doc["scenario_id"] = "abc123";
  for (int i = 0; i < 2; ++i) {
    doc["objects"][i]["id"] = 100 + i;
    doc["objects"][i]["height"] = 1.2;
    doc["objects"][i]["mark_as_expert"] = false;
    doc["objects"][i]["heading"] = json::array();
    for (int f = 0; f < kFrames; ++f) doc["objects"][i]["heading"].push_back(4.0);  // radians, beyond pi
  }
  doc["objects"][1]["id"] = 7.0;  // an integral float is an integer
  doc["metadata"] = {{"sdc_track_index", 1},
                     {"objects_of_interest", {100}},
                     {"tracks_to_predict", {{{"track_index", 0}, {"difficulty", 2}}}}};
  auto s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->id, "abc123");
  EXPECT_EQ(s->tracks[0].id, 100);
  EXPECT_EQ(s->tracks[1].id, 7);
  EXPECT_FLOAT_EQ(s->tracks[0].states[0].height, 1.2f);
  EXPECT_NEAR(s->tracks[0].states[0].heading, 4.0 - 2 * kPi, 1e-6);
  EXPECT_EQ(s->sdc_track_index, 1);
  EXPECT_EQ(s->objects_of_interest, std::vector<int32_t>{100});
  ASSERT_EQ(s->tracks_to_predict.size(), 1u);
  EXPECT_EQ(s->tracks_to_predict[0].difficulty, 2);
}

TEST(GpudriveJson, InvalidStepsWithPlaceholdersBecomeDefaultStates) {
  json doc = small_doc();
  for (int f : {0, 5}) {
    doc["objects"][0]["valid"][f] = false;
    doc["objects"][0]["position"][f] = {{"x", -10000.0}, {"y", -10000.0}, {"z", -10000.0}};
    doc["objects"][0]["heading"][f] = f == 0 ? -10000.0 : 0.0001;
    doc["objects"][0]["velocity"][f] = {{"x", -10000.0}, {"y", 0.0001}};
  }
  auto s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->tracks[0].states[0], ObjectState{});
  EXPECT_EQ(s->tracks[0].states[5], ObjectState{});
  EXPECT_TRUE(s->tracks[0].states[1].valid);
}

TEST(GpudriveJson, ReadsRoadKindsSubtypesAndPolygons) {
  json doc = small_doc();
  auto pts = [](int n) {
    json g = json::array();
    for (int k = 0; k < n; ++k) g.push_back({{"x", 1.0 * k}, {"y", 1.0 * k * k}, {"z", 2.0}});
    return g;
  };
  json closed = pts(4);
  closed.push_back(closed[0]);
  doc["roads"] = json::array({
      {{"type", "lane"}, {"geometry", pts(3)}, {"map_element_id", 2}, {"id", 40}},
      {{"type", "road_line"}, {"geometry", pts(2)}, {"map_element_id", 12}},
      {{"type", "road_edge"}, {"geometry", pts(2)}, {"map_element_id", 16}},
      {{"type", "stop_sign"}, {"geometry", pts(1)}, {"map_element_id", 17}},
      {{"type", "crosswalk"}, {"geometry", closed}, {"map_element_id", 18}},
      {{"type", "speed_bump"}, {"geometry", pts(4)}},
      {{"type", "driveway"}, {"geometry", pts(4)}, {"map_element_id", -1}},
  });
  auto s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  const auto& m = s->map_features;
  ASSERT_EQ(m.size(), 7u);
  EXPECT_EQ(m[0].id, 40);
  EXPECT_EQ(m[0].subtype, 2);  // surface street
  EXPECT_EQ(m[1].id, 1);       // no id: the index
  EXPECT_EQ(m[1].kind, MapFeatureKind::road_line);
  EXPECT_EQ(m[1].subtype, static_cast<int>(RoadLineType::solid_double_yellow));
  EXPECT_EQ(m[2].subtype, 2);  // median
  EXPECT_EQ(m[3].kind, MapFeatureKind::stop_sign);
  EXPECT_EQ(m[3].points.size(), 1u);
  EXPECT_EQ(m[4].points.size(), 4u);  // the repeated first point is dropped
  EXPECT_EQ(m[4].points, m[5].points);
  EXPECT_EQ(m[6].kind, MapFeatureKind::driveway);
  EXPECT_EQ(m[6].subtype, 0);
}

TEST(GpudriveJson, BuildsPerFrameSignals) {
  json doc = small_doc();
  // Lane 12 for frames 2..4, lane 5 at every frame (listed after 12 as a string key, but sorted first by id).
  doc["tl_states"]["12"] = {{"state", {"go", "caution", "flashing_stop"}},
                            {"x", {1.0, 1.0, 1.0}},
                            {"y", {2.0, 2.0, 2.0}},
                            {"z", {3.0, 3.0, 3.0}},
                            {"time_index", {2, 3, 4}},
                            {"lane_id", {12, 12, 12}}};
  json lane5 = {{"state", json::array()}, {"x", json::array()}, {"y", json::array()}, {"time_index", json::array()}};
  for (int f = 0; f < kFrames; ++f) {
    lane5["state"].push_back(f % 2 ? "arrow_go" : "unknown");
    lane5["x"].push_back(7.0);
    lane5["y"].push_back(8.0);
    lane5["time_index"].push_back(f);
  }
  doc["tl_states"]["5"] = lane5;
  auto s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->signals.size(), static_cast<size_t>(kFrames));
  EXPECT_EQ(s->signals[0].size(), 1u);
  ASSERT_EQ(s->signals[3].size(), 2u);
  EXPECT_EQ(s->signals[3][0].lane, 5);
  EXPECT_EQ(s->signals[3][0].state, SignalState::arrow_go);
  EXPECT_EQ(s->signals[3][0].stop_point, (MapPoint{7, 8, 0}));  // z optional
  EXPECT_EQ(s->signals[3][1].lane, 12);
  EXPECT_EQ(s->signals[3][1].state, SignalState::caution);
  EXPECT_EQ(s->signals[4][1].state, SignalState::flashing_stop);
  EXPECT_EQ(s->signals[3][1].stop_point, (MapPoint{1, 2, 3}));
  EXPECT_TRUE(s->signals[3][1].has_stop_point);

  // Lanes with no entries are no lights.
  doc["tl_states"] = {{"5", {{"state", json::array()}, {"x", json::array()}, {"y", json::array()},
                             {"time_index", json::array()}}}};
  s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(s->signals.empty());
  doc.erase("tl_states");
  EXPECT_TRUE(parse(doc).ok());
}

TEST(GpudriveJson, AcceptsOtherAndUnsetTypes) {
  json doc = small_doc();
  doc["objects"][0]["type"] = "other";
  doc["objects"][1]["type"] = "unset";
  auto s = parse(doc);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->tracks[0].type, ObjectType::other);
  EXPECT_EQ(s->tracks[1].type, ObjectType::unset);
  EXPECT_FLOAT_EQ(s->tracks[1].states[0].height, 1.5f);
}

TEST(GpudriveJson, NamesWrongTypesAndMissingKeys) {
  EXPECT_ERROR("[]", "expected an object, got array");
  json doc = small_doc();
  doc.erase("name");
  EXPECT_ERROR(doc, "missing required key \"name\"");
  doc = small_doc();
  doc["name"] = 3;
  EXPECT_ERROR(doc, "name: expected a string, got number");
  doc = small_doc();
  doc.erase("objects");
  EXPECT_ERROR(doc, "missing required key \"objects\"");
  doc = small_doc();
  doc["objects"] = json::array();
  EXPECT_ERROR(doc, "objects: is empty");
  doc = small_doc();
  doc["roads"] = json::object();
  EXPECT_ERROR(doc, "roads: expected an array, got object");
  doc = small_doc();
  doc["objects"][1]["position"][3]["x"] = "12";
  EXPECT_ERROR(doc, "objects[1].position[3].x: expected a number, got string");
  doc = small_doc();
  doc["objects"][1]["position"][3].erase("y");
  EXPECT_ERROR(doc, "objects[1].position[3]: missing required key \"y\"");
  doc = small_doc();
  doc["objects"][0]["valid"][2] = 1;
  EXPECT_ERROR(doc, "objects[0].valid[2]: expected a boolean, got number");
  doc = small_doc();
  doc["objects"][0]["velocity"][6] = {1.0, 2.0};
  EXPECT_ERROR(doc, "objects[0].velocity[6]: expected an object, got array");
  doc = small_doc();
  doc["objects"][0]["velocity"][6]["y"] = nullptr;
  EXPECT_ERROR(doc, "objects[0].velocity[6].y: expected a number, got null");
  doc = small_doc();
  doc["objects"][0]["heading"][6] = true;
  EXPECT_ERROR(doc, "objects[0].heading[6]: expected a number, got boolean");
  doc = small_doc();
  doc["objects"][0].erase("width");
  EXPECT_ERROR(doc, "objects[0]: missing required key \"width\"");
  doc = small_doc();
  doc["objects"][0]["length"] = -1.0;
  EXPECT_ERROR(doc, "objects[0].length: is negative");
  doc = small_doc();
  doc["objects"][1]["type"] = "truck";
  EXPECT_ERROR(doc, "objects[1].type: unknown object type \"truck\"");
  doc = small_doc();
  doc["objects"][1]["valid"][0] = false;  // invalid steps are type-checked too
  doc["objects"][1]["position"][0]["x"] = "n/a";
  EXPECT_ERROR(doc, "objects[1].position[0].x: expected a number, got string");
  doc = small_doc();
  doc["roads"][0].erase("geometry");
  EXPECT_ERROR(doc, "roads[0]: missing required key \"geometry\"");
  doc = small_doc();
  doc["roads"][0]["geometry"][1]["z"] = "high";
  EXPECT_ERROR(doc, "roads[0].geometry[1].z: expected a number, got string");
  doc = small_doc();
  doc["metadata"] = {{"sdc_track_index", 2}};
  EXPECT_ERROR(doc, "metadata.sdc_track_index: 2 is outside [-1, 1]");
  doc = small_doc();
  doc["metadata"] = {{"sdc_track_index", 0.5}};
  EXPECT_ERROR(doc, "metadata.sdc_track_index: expected an integer, got 0.5");
  doc = small_doc();
  doc["metadata"] = {{"objects_of_interest", {5}}};
  EXPECT_ERROR(doc, "metadata.objects_of_interest[0]: 5 is not the id of an object");
  doc = small_doc();
  doc["metadata"] = {{"tracks_to_predict", {{{"track_index", 0}, {"difficulty", 3}}}}};
  EXPECT_ERROR(doc, "metadata.tracks_to_predict[0].difficulty: 3 is outside [0, 2]");
}

TEST(GpudriveJson, NamesInconsistentIdsAndLengths) {
  json doc = small_doc();
  doc["objects"][0]["heading"].erase(3);
  EXPECT_ERROR(doc, "objects[0].heading: has 10 entries, but objects[0].position has 11");
  doc = small_doc();
  doc["objects"][1]["valid"].push_back(true);
  EXPECT_ERROR(doc, "objects[1].valid: has 12 entries, but objects[0].position has 11");
  doc = small_doc();
  for (auto& o : doc["objects"])
    for (const char* k : {"position", "heading", "velocity", "valid"}) o[k].erase(0);
  EXPECT_ERROR(doc, "objects[0].position: has 10 frames; a scenario needs at least 11");
  doc = small_doc();
  doc["objects"][1]["id"] = 4;
  EXPECT_ERROR(doc, "objects[1]: has \"id\" but objects[0] has none");
  doc = small_doc();
  doc["objects"][0]["id"] = 4;
  doc["objects"][1]["id"] = 4;
  EXPECT_ERROR(doc, "objects[1].id: 4 is used by an earlier object");
  doc = small_doc();
  doc["objects"][0]["id"] = 1e12;
  doc["objects"][1]["id"] = 1;
  EXPECT_ERROR(doc, "objects[0].id: 1000000000000 is outside");
  doc = small_doc();
  doc["roads"].push_back(doc["roads"][0]);
  doc["roads"][1]["id"] = 0;
  EXPECT_ERROR(doc, "roads[1]: map feature id 0 is used by an earlier road");
}

TEST(GpudriveJson, RejectsPlaceholdersAndNonFiniteValuesInValidSteps) {
  json doc = small_doc();
  doc["objects"][0]["position"][4]["x"] = -10000.0;
  EXPECT_ERROR(doc, "objects[0].position[4].x: holds the placeholder -10000");
  doc = small_doc();
  doc["objects"][1]["heading"][7] = -10000;
  EXPECT_ERROR(doc, "objects[1].heading[7]: holds the placeholder");
  doc = small_doc();
  doc["objects"][1]["velocity"][7]["y"] = -10000.0;
  EXPECT_ERROR(doc, "objects[1].velocity[7].y: holds the placeholder");
  doc = small_doc();
  doc["objects"][1]["velocity"][7]["y"] = 1e300;
  EXPECT_ERROR(doc, "objects[1].velocity[7].y: 1e+300 is outside the float range");
  // JSON has no NaN or infinity; the tokens some writers emit are syntax errors at the field.
  std::string text = small_doc().dump();
  std::string nan_text = text;
  nan_text.replace(nan_text.find("\"x\":4.0"), 7, "\"x\":NaN");
  EXPECT_ERROR(nan_text, "objects[0].position[4].x: invalid JSON");
  std::string inf_text = text;
  inf_text.replace(inf_text.find("\"x\":4.0"), 7, "\"x\":1e999");
  EXPECT_ERROR(inf_text, "objects[0].position[4].x: invalid JSON");
  EXPECT_ERROR(inf_text, "number overflow");
}

TEST(GpudriveJson, NamesBadRoads) {
  json doc = small_doc();
  doc["roads"][0]["type"] = "bridge";
  EXPECT_ERROR(doc, "roads[0].type: unknown road type \"bridge\"");
  doc = small_doc();
  doc["roads"][0]["map_element_id"] = 15;
  EXPECT_ERROR(doc, "roads[0].map_element_id: 15 denotes a road_edge, but type is \"lane\"");
  doc = small_doc();
  doc["roads"][0]["map_element_id"] = 4;
  EXPECT_ERROR(doc, "roads[0].map_element_id: 4 is not a GPUDrive MapElementId");
  doc = small_doc();
  doc["roads"][0]["map_element_id"] = 21;
  EXPECT_ERROR(doc, "roads[0].map_element_id: 21 is outside [-1, 20]");
  doc = small_doc();
  doc["roads"][0]["geometry"] = json::array();
  EXPECT_ERROR(doc, "roads[0].geometry: is empty");
  doc = small_doc();
  doc["roads"][0]["type"] = "stop_sign";
  EXPECT_ERROR(doc, "roads[0].geometry: a stop sign has one point");
}

TEST(GpudriveJson, NamesBadLights) {
  auto with_light = [](json entry, std::string key = "7") {
    json doc = small_doc();
    doc["tl_states"][key] = std::move(entry);
    return doc;
  };
  const json good = {{"state", {"go", "stop"}}, {"x", {1.0, 1.0}}, {"y", {2.0, 2.0}}, {"z", {0.0, 0.0}},
                     {"time_index", {0, 1}}};
  EXPECT_TRUE(parse(with_light(good)).ok());
  json e = good;
  e["state"][1] = "purple";
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].state[1]: unknown light state \"purple\"");
  EXPECT_ERROR(with_light(good, "abc"), "tl_states[\"abc\"]: key is not a lane id");
  EXPECT_ERROR(with_light(good, "7.5"), "tl_states[\"7.5\"]: key is not a lane id");
  EXPECT_ERROR(with_light(good, "07"), "tl_states[\"07\"]: key is not a lane id");
  EXPECT_ERROR(with_light(good, ""), "tl_states[\"\"]: key is not a lane id");
  e = good;
  e["x"].push_back(3.0);
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].x: has 3 entries, but state has 2");
  e = good;
  e["time_index"][1] = 11;
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].time_index[1]: 11 is outside [0, 10]");
  e = good;
  e["time_index"][1] = 0;
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].time_index[1]: frame 0 appears twice");
  e = good;
  e.erase("time_index");
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"]: missing required key \"time_index\"");
  e = good;
  e["y"][0] = -10000.0;
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].y[0]: holds the placeholder");
  e = good;
  e["lane_id"] = {7, 8};
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].lane_id[1]: 8 differs from the key's lane id 7");
  e = good;
  e["state"] = "go";
  EXPECT_ERROR(with_light(e), "tl_states[\"7\"].state: expected an array, got string");
  json doc = small_doc();
  doc["tl_states"] = json::array();
  EXPECT_ERROR(doc, "tl_states: expected an object, got array");
}

TEST(GpudriveJson, NamesSyntaxErrors) {
  const std::string text = small_doc().dump();
  // Truncated: the message says where the document stopped.
  const size_t cut = text.find("\"velocity\"") + 20;
  EXPECT_ERROR(text.substr(0, cut), "objects[0].velocity");
  EXPECT_ERROR(text.substr(0, cut), "invalid JSON");
  EXPECT_ERROR("", "invalid JSON");
  EXPECT_ERROR(text + " x", "invalid JSON");
  // Invalid UTF-8 inside a string; the message itself stays printable ASCII.
  std::string bad = text;
  bad.replace(bad.find("pedestrian"), 10, "pede\xff\xfe");
  std::string msg = error_of(bad);
  EXPECT_NE(msg.find("objects[1].type: invalid JSON"), std::string::npos) << msg;
  EXPECT_NE(msg.find("UTF-8"), std::string::npos) << msg;
  EXPECT_TRUE(std::all_of(msg.begin(), msg.end(), [](char c) { return c >= 0x20 && c < 0x7f; })) << msg;
  // Duplicate keys would otherwise be dropped silently.
  std::string dup = text;
  dup.replace(dup.find("\"width\""), 7, "\"length\"");
  EXPECT_ERROR(dup, "objects[0]: duplicate key \"length\"");
  // Deep nesting is refused before it builds a deep tree.
  EXPECT_ERROR(std::string(100000, '[') + std::string(100000, ']'), "nesting deeper than 32 levels");
  std::string deep = text;
  deep.replace(deep.find("\"goalPosition\":") + 15, 0, std::string(40, '['));
  EXPECT_ERROR(deep, "objects[0].goalPosition");
  // Control characters in keys are escaped in messages.
  json doc = small_doc();
  doc["tl_states"]["\x01"] = json::object();
  EXPECT_ERROR(doc, "tl_states[\"\\x01\"]: key is not a lane id");
}

TEST(GpudriveJson, NeverCrashesOnTruncationsOrByteFlips) {
  const std::string text = small_doc().dump();
  for (size_t n = 0; n < text.size(); ++n) {
    auto s = scenario_from_gpudrive_json(std::string_view(text).substr(0, n), "t.json");
    ASSERT_FALSE(s.ok()) << n;
  }
  for (size_t i = 0; i < text.size(); i += 3) {
    std::string t = text;
    t[i] = static_cast<char>(t[i] ^ 0x5A);
    (void)scenario_from_gpudrive_json(t, "t.json");
  }
}

}  // namespace
}  // namespace ss
