#include "offline/render/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "engine/map/focus.h"
#include "offline/render/style.h"
#include "engine/scenario/read.h"
#include "engine/tokens/light.h"
#include "tests/unit/offline/render/xml_dom.h"

namespace ss {
namespace {

using testing::XmlNode;
using testing::XmlReader;

constexpr double kRadToDeg = 180 / kPi;

const Scenario& real_scenario() {
  static const Scenario s = [] {
    auto all = read_scenarios(SS_DATA_DIR "/womd/tfrecord/motion_data_one_scenario.tfrecord");
    EXPECT_TRUE(all.ok()) << all.status();
    return all.ok() ? (*all)[0] : Scenario{};
  }();
  return s;
}

std::unique_ptr<XmlNode> render_and_parse(const Scenario& s, const RenderOptions& o, std::string* svg_out = nullptr) {
  auto svg = render_scene_svg(s, o);
  EXPECT_TRUE(svg.ok()) << svg.status();
  if (!svg.ok()) return nullptr;
  std::string error;
  auto root = XmlReader::parse(*svg, &error);
  EXPECT_NE(root, nullptr) << "not well-formed XML: " << error;
  if (svg_out) *svg_out = *svg;
  return root;
}

// "translate(1.5 -2)" or "1.5 -2" -> {1.5, -2}; "rotate(-90)" or "-90" -> {-90, 0}.
Vec2 transform_args(std::string t) {
  if (auto p = t.find('('); p != std::string::npos) t = t.substr(p + 1, t.find(')') - p - 1);
  Vec2 v;
  std::sscanf(t.c_str(), "%lf %lf", &v.x, &v.y);
  return v;
}

// The value an element shows at drawn frame i of n: its SMIL animation's (discrete keyTimes) or else its attribute.
// `key` names an attribute, or "translate"/"rotate" for the transform of that type.
std::string value_at(const XmlNode& el, const std::string& key, int i, int n) {
  const bool transform = key == "translate" || key == "rotate";
  for (const auto& c : el.children) {
    const bool match = transform ? c->name == "animateTransform" && c->attr("type") == key
                                 : c->name == "animate" && c->attr("attributeName") == key;
    if (!match) continue;
    EXPECT_EQ(c->attr("calcMode"), "discrete");
    std::vector<std::string> times, values;
    for (std::string list : {c->attr("keyTimes"), c->attr("values")}) {
      std::vector<std::string>& out = times.empty() ? times : values;
      size_t b = 0;
      for (size_t e; (e = list.find(';', b)) != std::string::npos; b = e + 1) out.push_back(list.substr(b, e - b));
      out.push_back(list.substr(b));
    }
    EXPECT_EQ(times.size(), values.size());
    std::string v = values[0];
    for (size_t k = 0; k < times.size(); ++k)
      if (std::stod(times[k]) <= (i + 0.5) / n) v = values[k];
    return v;
  }
  if (transform) return el.attr("transform");
  if (key == "visibility" && el.attr(key).empty()) return "visible";
  return el.attr(key);
}

std::vector<const XmlNode*> children_of(const XmlNode& root, const std::string& id) {
  std::vector<const XmlNode*> out;
  const XmlNode* g = root.by_id(id);
  EXPECT_NE(g, nullptr) << "no #" << id;
  if (g)
    for (const auto& c : g->children) out.push_back(c.get());
  return out;
}

const Track* track_by_id(const Scenario& s, const std::string& id) {
  for (const Track& t : s.tracks)
    if (std::to_string(t.id) == id) return &t;
  return nullptr;
}

Vec2 map_centre(const XmlNode& root) {
  const XmlNode* map = root.by_id("map");
  return {std::stod(map->attr("data-centre-x")), std::stod(map->attr("data-centre-y"))};
}

TEST(Render, StillDrawsEveryAgentValidAtTheFrameWithTheSdcHighlightedAtTheCentre) {
  const Scenario& s = real_scenario();
  ASSERT_EQ(s.sdc_track_index, 82);
  const int now = s.current_time_index;
  auto root = render_and_parse(s, {.radius_m = 2000});  // everything in view
  ASSERT_NE(root, nullptr);
  EXPECT_EQ(root->name, "svg");

  std::set<std::string> want, got;
  for (const Track& t : s.tracks)
    if (t.states[now].valid) want.insert(std::to_string(t.id));
  const auto agents = children_of(*root, "agents");
  for (const XmlNode* a : agents) {
    EXPECT_TRUE(a->has_class("agent"));
    got.insert(a->attr("data-id"));
  }
  EXPECT_EQ(agents.size(), want.size());
  EXPECT_EQ(got, want);

  // Exactly one SDC, drawn last (on top), at the centre of the view.
  const Track& sdc = s.tracks[s.sdc_track_index];
  int sdcs = 0;
  for (const XmlNode* a : agents) sdcs += a->has_class("sdc");
  EXPECT_EQ(sdcs, 1);
  ASSERT_FALSE(agents.empty());
  EXPECT_TRUE(agents.back()->has_class("sdc"));
  EXPECT_EQ(agents.back()->attr("data-id"), std::to_string(sdc.id));
  EXPECT_EQ(agents.back()->all("circle").size(), 1u);  // the halo
  const Vec2 at = transform_args(agents.back()->attr("transform"));
  EXPECT_NEAR(at.x, 0, 0.01);
  EXPECT_NEAR(at.y, 0, 0.01);
  const XmlNode* map = root->by_id("map");
  ASSERT_NE(map, nullptr);
  EXPECT_EQ(map->attr("viewBox"), "-2000 -2000 4000 4000");
  EXPECT_NEAR(map_centre(*root).x, sdc.states[now].x, 0.01);
  EXPECT_NEAR(map_centre(*root).y, sdc.states[now].y, 0.01);

  // Caption: the scenario id and the frame.
  const auto texts = children_of(*root, "caption");
  ASSERT_EQ(texts.size(), 1u);
  EXPECT_NE(texts[0]->text.find("637f20cafde22ff8"), std::string::npos);
  EXPECT_NE(texts[0]->text.find("frame 10/90"), std::string::npos);
  EXPECT_NE(root->by_id("legend"), nullptr);
}

TEST(Render, AgentsSitAtTheirPoseWithNorthUpAndOnlyThoseNearTheViewAreDrawn) {
  const Scenario& s = real_scenario();
  const int step = 40;
  std::string svg;
  auto root = render_and_parse(s, {.step = step}, &svg);
  ASSERT_NE(root, nullptr);
  EXPECT_EQ(root->by_id("map")->attr("viewBox"), "-80 -80 160 160");
  const ObjectState& sdc = s.tracks[s.sdc_track_index].states[step];
  const Vec2 c = map_centre(*root);
  EXPECT_NEAR(c.x, sdc.x, 0.01);
  EXPECT_NEAR(c.y, sdc.y, 0.01);

  size_t near = 0;
  for (const Track& t : s.tracks) {
    const ObjectState& st = t.states[step];
    near += st.valid && std::abs(st.x - c.x) <= 80 + kViewMarginM && std::abs(st.y - c.y) <= 80 + kViewMarginM;
  }
  const auto agents = children_of(*root, "agents");
  EXPECT_EQ(agents.size(), near);
  EXPECT_LT(near, s.tracks.size());  // the radius does cut some away
  for (const XmlNode* a : agents) {
    const Track* t = track_by_id(s, a->attr("data-id"));
    ASSERT_NE(t, nullptr);
    const ObjectState& st = t->states[step];
    ASSERT_TRUE(st.valid);
    const Vec2 at = transform_args(a->attr("transform"));
    EXPECT_NEAR(at.x, st.x - c.x, 0.011);
    EXPECT_NEAR(at.y, c.y - st.y, 0.011);  // y flipped: north is up
    ASSERT_EQ(a->all("g").size(), 1u);
    const double rot = transform_args(a->all("g")[0]->attr("transform")).x;
    EXPECT_NEAR(std::remainder(rot + st.heading * kRadToDeg, 360), 0, 0.06);
    EXPECT_TRUE(a->has_class(agent_class(t->type)));
  }
  EXPECT_LT(svg.size(), 200'000u);
}

Scenario small_scenario(int frames) {
  Scenario s;
  s.id = "hand-made";
  for (int i = 0; i < frames; ++i) s.timestamps.push_back(0.1 * i);
  s.signals.resize(frames);
  return s;
}

Track moving_track(int id, ObjectType type, int frames, Vec2 start, Vec2 velocity, float heading) {
  Track t;
  t.id = id;
  t.type = type;
  for (int i = 0; i < frames; ++i)
    t.states.push_back({.x = start.x + 0.1 * i * velocity.x, .y = start.y + 0.1 * i * velocity.y, .length = 4.5f,
                        .width = 2, .height = 1.5f, .heading = heading, .valid = true});
  return t;
}

TEST(Render, NorthIsUpAndHeadingsTurnTheRightWay) {
  Scenario s = small_scenario(1);
  s.tracks.push_back(moving_track(1, ObjectType::vehicle, 1, {100, 200}, {}, 0));                  // SDC, east
  s.tracks.push_back(moving_track(2, ObjectType::cyclist, 1, {100, 220}, {}, float(kPi / 2)));    // north of it
  s.tracks.push_back(moving_track(3, ObjectType::pedestrian, 1, {110, 200}, {}, float(-kPi / 2)));  // east of it
  s.sdc_track_index = 0;
  auto root = render_and_parse(s, {});
  ASSERT_NE(root, nullptr);
  std::map<std::string, std::pair<Vec2, double>> pose;
  for (const XmlNode* a : children_of(*root, "agents"))
    pose[a->attr("data-id")] = {transform_args(a->attr("transform")),
                                transform_args(a->all("g")[0]->attr("transform")).x};
  ASSERT_EQ(pose.size(), 3u);
  EXPECT_NEAR(pose["2"].first.y, -20, 1e-9);  // north: up, towards smaller SVG y
  EXPECT_NEAR(pose["3"].first.x, 10, 1e-9);   // east: right
  EXPECT_NEAR(pose["1"].second, 0, 1e-9);     // heading east: unrotated
  EXPECT_NEAR(pose["2"].second, -90, 1e-9);   // heading north: the box's front points up the screen
  EXPECT_NEAR(pose["3"].second, 90, 1e-9);
}

TEST(Render, LightsTakeEachFramesStateColours) {
  const Scenario& s = real_scenario();
  for (int step : {0, s.current_time_index, 50, 90}) {
    auto root = render_and_parse(s, {.step = step, .radius_m = 2000});
    ASSERT_NE(root, nullptr);
    std::map<std::string, int> want, got;
    for (const SignalLaneState& ls : s.signals[step]) ++want[light_state_name(light_state_from_womd(ls.state))];
    const auto lights = children_of(*root, "lights");
    for (const XmlNode* l : lights) {
      for (LightState st : {LightState::unknown, LightState::green, LightState::yellow, LightState::red}) {
        if (!l->has_class(light_state_name(st))) continue;
        ++got[light_state_name(st)];
        EXPECT_EQ(l->attr("fill"), light_colour(st));
      }
    }
    EXPECT_EQ(lights.size(), s.signals[step].size()) << "frame " << step;
    EXPECT_EQ(got, want) << "frame " << step;
  }
  // This scenario's lights do change: red and unknown alternate for some lanes.
  std::set<int> states;
  for (const auto& frame : s.signals)
    for (const SignalLaneState& ls : frame) states.insert(static_cast<int>(light_state_from_womd(ls.state)));
  EXPECT_GE(states.size(), 2u);
}

TEST(Render, LightsOfAGpudriveJsonScenario) {
  auto all = read_scenarios(SS_DATA_DIR "/womd/json/val/womd_27d205cc.json");
  ASSERT_TRUE(all.ok()) << all.status();
  const Scenario& s = (*all)[0];
  for (int step : {s.current_time_index, 85}) {
    auto root = render_and_parse(s, {.step = step, .radius_m = 2000});
    ASSERT_NE(root, nullptr);
    std::map<std::string, int> want, got;
    for (const SignalLaneState& ls : s.signals[step]) ++want[light_state_name(light_state_from_womd(ls.state))];
    for (const XmlNode* l : children_of(*root, "lights"))
      for (const char* name : {"unknown", "green", "yellow", "red"}) got[name] += l->has_class(name);
    std::erase_if(got, [](const auto& kv) { return kv.second == 0; });
    EXPECT_EQ(got, want) << "frame " << step;
    EXPECT_FALSE(want.empty());
  }
}

TEST(Render, MapFeaturesOfEveryKind) {
  const Scenario& s = real_scenario();
  auto root = render_and_parse(s, {.radius_m = 2000});
  ASSERT_NE(root, nullptr);
  EXPECT_EQ(children_of(*root, "crosswalks").size(), 4u);
  EXPECT_EQ(children_of(*root, "stop-signs").size(), 8u);
  EXPECT_EQ(children_of(*root, "speed-bumps").size(), 3u);
  EXPECT_NE(root->by_id("lanes"), nullptr);
  EXPECT_NE(root->by_id("lane-centres"), nullptr);
  EXPECT_NE(root->by_id("road-edges"), nullptr);
  // Every road line is drawn, doubles twice.
  size_t want = 0;
  for (const MapFeature& f : s.map_features)
    if (f.kind == MapFeatureKind::road_line)
      want += f.subtype == 3 || f.subtype == 5 || f.subtype == 7 || f.subtype == 8 ? 2 : 1;
  EXPECT_EQ(children_of(*root, "road-lines").size(), want);
  // Zebra stripes are patterns the crosswalks refer to.
  for (const XmlNode* c : children_of(*root, "crosswalks")) {
    const std::string fill = c->attr("fill");
    ASSERT_EQ(fill.rfind("url(#", 0), 0u) << fill;
    EXPECT_NE(root->by_id(fill.substr(5, fill.size() - 6)), nullptr) << fill;
  }
}

TEST(Render, RoadLinesAreStyledByType) {
  Scenario s = small_scenario(1);
  const std::pair<RoadLineType, std::vector<std::string>> cases[] = {
      {RoadLineType::broken_single_white, {"line white dashed"}},
      {RoadLineType::solid_single_white, {"line white"}},
      {RoadLineType::solid_double_white, {"line white", "line white"}},
      {RoadLineType::broken_single_yellow, {"line yellow dashed"}},
      {RoadLineType::broken_double_yellow, {"line yellow dashed", "line yellow dashed"}},
      {RoadLineType::solid_single_yellow, {"line yellow"}},
      {RoadLineType::solid_double_yellow, {"line yellow", "line yellow"}},
      {RoadLineType::passing_double_yellow, {"line yellow", "line yellow dashed"}},
  };
  for (const auto& [type, classes] : cases) {
    MapFeature line;
    line.kind = MapFeatureKind::road_line;
    line.subtype = static_cast<int32_t>(type);
    line.points = {{0, 0, 0}, {10, 0, 0}, {20, 1, 0}};
    s.map_features = {line};
    auto root = render_and_parse(s, {});
    ASSERT_NE(root, nullptr);
    std::vector<std::string> got;
    for (const XmlNode* l : children_of(*root, "road-lines")) got.push_back(l->attr("class"));
    EXPECT_EQ(got, classes) << static_cast<int>(type);
  }
}

TEST(Render, AnimationShowsEveryFrameOfEveryAgentAndLight) {
  const Scenario& s = real_scenario();
  const int n = s.num_frames();
  std::string svg;
  auto root = render_and_parse(s, {.animate = true}, &svg);
  ASSERT_NE(root, nullptr);
  EXPECT_LT(svg.size(), 3'000'000u);  // 91 frames, 83 agents
  EXPECT_FALSE(root->all("animateTransform").empty());
  EXPECT_EQ(children_of(*root, "caption").size(), static_cast<size_t>(n));
  for (const XmlNode* a : root->all("animate")) EXPECT_EQ(a->attr("dur"), "9.1s");

  const Vec2 origin = map_centre(*root);
  EXPECT_NEAR(origin.x, scenario_focus(s).x, 0.01);
  const XmlNode* map = root->by_id("map");
  const Track& sdc = s.tracks[s.sdc_track_index];
  const auto agents = children_of(*root, "agents");
  EXPECT_GT(agents.size(), 50u);
  for (int i = 0; i < n; ++i) {
    // The view follows the SDC.
    const Vec2 corner = transform_args(value_at(*map, "viewBox", i, n));
    EXPECT_NEAR(corner.x + 80, sdc.states[i].x - origin.x, 0.011) << i;
    EXPECT_NEAR(corner.y + 80, origin.y - sdc.states[i].y, 0.011) << i;
    int shown = 0;
    for (const XmlNode* a : agents) {
      const Track* t = track_by_id(s, a->attr("data-id"));
      ASSERT_NE(t, nullptr);
      const ObjectState& st = t->states[i];
      const bool visible = value_at(*a, "visibility", i, n) == "visible";
      ASSERT_EQ(visible, st.valid) << "track " << t->id << " frame " << i;
      if (!visible) continue;
      ++shown;
      const Vec2 at = transform_args(value_at(*a, "translate", i, n));
      ASSERT_NEAR(at.x, st.x - origin.x, 0.011) << "track " << t->id << " frame " << i;
      ASSERT_NEAR(at.y, origin.y - st.y, 0.011) << "track " << t->id << " frame " << i;
      const double rot = transform_args(value_at(*a->all("g")[0], "rotate", i, n)).x;
      ASSERT_NEAR(std::remainder(rot + st.heading * kRadToDeg, 360), 0, 0.06) << "track " << t->id << " frame " << i;
    }
    EXPECT_GT(shown, 0);
    // Lights: listed lanes in their state's colour, the rest hidden.
    std::map<std::string, LightState> state;
    for (const SignalLaneState& ls : s.signals[i]) state[std::to_string(ls.lane)] = light_state_from_womd(ls.state);
    int lit = 0;
    for (const XmlNode* l : children_of(*root, "lights")) {
      auto it = state.find(l->attr("data-lane"));
      const bool visible = value_at(*l, "visibility", i, n) == "visible";
      EXPECT_EQ(visible, it != state.end()) << "lane " << l->attr("data-lane") << " frame " << i;
      if (it == state.end()) continue;
      ++lit;
      EXPECT_EQ(value_at(*l, "fill", i, n), light_colour(it->second)) << "lane " << it->first << " frame " << i;
    }
    EXPECT_EQ(lit, static_cast<int>(state.size())) << i;
    // One caption per frame, shown only then.
    const auto captions = children_of(*root, "caption");
    for (int k = 0; k < n; k += 30)
      EXPECT_EQ(value_at(*captions[k], "visibility", i, n), k == i ? "visible" : "hidden") << k << " at " << i;
  }
}

TEST(Render, AgentsAppearAndDisappearWithValidity) {
  Scenario s = small_scenario(10);
  s.tracks.push_back(moving_track(1, ObjectType::vehicle, 10, {0, 0}, {5, 0}, 0));
  s.tracks.push_back(moving_track(2, ObjectType::pedestrian, 10, {5, 5}, {0, 3}, float(kPi / 2)));
  for (int i : {0, 1, 2, 7}) s.tracks[1].states[i].valid = false;
  s.sdc_track_index = 0;
  auto root = render_and_parse(s, {.animate = true});
  ASSERT_NE(root, nullptr);
  const XmlNode* ped = nullptr;
  for (const XmlNode* a : children_of(*root, "agents"))
    if (a->attr("data-id") == "2") ped = a;
  ASSERT_NE(ped, nullptr);
  for (int i = 0; i < 10; ++i)
    EXPECT_EQ(value_at(*ped, "visibility", i, 10), s.tracks[1].states[i].valid ? "visible" : "hidden") << i;
  // The trail follows the agent, and is hidden while there are not two valid positions behind it.
  const XmlNode* trail = nullptr;
  for (const XmlNode* t : children_of(*root, "trails"))
    if (t->attr("data-id") == "2") trail = t;
  ASSERT_NE(trail, nullptr);
  EXPECT_EQ(value_at(*trail, "visibility", 3, 10), "hidden");
  EXPECT_EQ(value_at(*trail, "visibility", 5, 10), "visible");
  EXPECT_EQ(value_at(*trail, "visibility", 7, 10), "hidden");
  // A still of a frame where the agent is invalid leaves it out.
  auto still = render_and_parse(s, {.step = 7});
  ASSERT_NE(still, nullptr);
  EXPECT_EQ(children_of(*still, "agents").size(), 1u);
}

TEST(Render, TextIsEscaped) {
  Scenario s = small_scenario(1);
  s.id = "a<b&\"c'>";
  auto root = render_and_parse(s, {});
  ASSERT_NE(root, nullptr);
  ASSERT_FALSE(root->all("title").empty());
  EXPECT_EQ(root->all("title")[0]->text, "scenario a<b&\"c'>");
}

TEST(Render, Errors) {
  const Scenario& s = real_scenario();
  auto bad_step = render_scene_svg(s, {.step = 91});
  ASSERT_FALSE(bad_step.ok());
  EXPECT_EQ(bad_step.status().code(), absl::StatusCode::kOutOfRange);
  EXPECT_NE(bad_step.status().message().find("step 91"), std::string::npos) << bad_step.status();
  EXPECT_NE(bad_step.status().message().find("637f20cafde22ff8"), std::string::npos) << bad_step.status();
  EXPECT_NE(bad_step.status().message().find("0..90"), std::string::npos) << bad_step.status();
  EXPECT_FALSE(render_scene_svg(s, {.step = -2}).ok());
  EXPECT_FALSE(render_scene_svg(s, {.radius_m = 0}).ok());
  EXPECT_FALSE(render_scene_svg(s, {.radius_m = std::nan("")}).ok());
  EXPECT_FALSE(render_scene_svg(s, {.step = 3, .animate = true}).ok());
  Scenario no_frames;
  no_frames.id = "empty";
  auto empty = render_scene_svg(no_frames, {});
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().message().find("empty"), std::string::npos);
  EXPECT_TRUE(render_scene_svg(s, {.step = 90}).ok());
}

TEST(XmlReader, RejectsMalformedDocuments) {
  std::string error;
  EXPECT_NE(XmlReader::parse("<?xml version=\"1.0\"?><a x=\"1\"><b/>t&amp;<c></c></a>\n", &error), nullptr) << error;
  for (const char* bad : {"<a><b></a></b>", "<a>", "<a x=1/>", "<a>&nope;</a>", "<a x=\"1\" x=\"2\"/>", "<a/><b/>",
                          "<a>x < y</a>", "<a x=\"1\"y=\"2\"/>"})
    EXPECT_EQ(XmlReader::parse(bad, &error), nullptr) << bad;
}

}  // namespace
}  // namespace ss
