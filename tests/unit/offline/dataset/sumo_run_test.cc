// The conventions checked against SUMO itself: a hand-made crossroads (netconvert) with a signal, sidewalks and
// crossings, cars driving through it (sumo), and the converter's view of the run compared with what SUMO says in
// its own terms (lane positions, lane ids). Skipped when SUMO is not installed.
#include <fcntl.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "offline/dataset/sumo_events.h"
#include "offline/dataset/sumo_fcd.h"
#include "offline/dataset/sumo_map.h"
#include "offline/dataset/sumo_net.h"
#include "offline/dataset/xml_scan.h"

extern char** environ;

namespace ss {
namespace {

namespace fs = std::filesystem;

bool on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  for (std::string d; std::getline(dirs, d, ':');)
    if (::access((d + "/" + program).c_str(), X_OK) == 0) return true;
  return false;
}

// Runs argv in `dir` (stdout and stderr to files there); the exit status.
int run(const std::vector<std::string>& argv, const std::string& dir) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addchdir_np(&fa, dir.c_str());
  posix_spawn_file_actions_addopen(&fa, 1, (dir + "/" + argv[0] + ".out").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, (dir + "/" + argv[0] + ".err").c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid;
  const int err = posix_spawnp(&pid, argv[0].c_str(), &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (err) return -1;
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

Vec2 point_along(const std::vector<Vec2>& shape, double s) {
  for (size_t i = 0; i + 1 < shape.size(); ++i) {
    const double len = distance(shape[i], shape[i + 1]);
    if (s <= len || i + 2 == shape.size()) return shape[i] + (s / len) * (shape[i + 1] - shape[i]);
    s -= len;
  }
  return shape.back();
}

class SumoRunTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!on_path("sumo") || !on_path("netconvert")) return;
    char templ[] = "/tmp/scenestreamer-sumo-test-XXXXXX";
    dir_ = new std::string(mkdtemp(templ));
    const std::string& d = *dir_;
    write(d + "/x.nod.xml", R"(<nodes>
  <node id="C" x="0" y="0" type="traffic_light"/>
  <node id="W" x="-150" y="0" type="priority"/> <node id="E" x="150" y="0" type="priority"/>
  <node id="S" x="0" y="-150" type="priority"/> <node id="N" x="0" y="150" type="priority"/>
</nodes>)");
    std::string edges = "<edges>\n";
    for (const char* o : {"W", "E", "S", "N"})
      edges += std::string("  <edge id=\"") + o + "C\" from=\"" + o + "\" to=\"C\" numLanes=\"1\" speed=\"13.89\"/>\n" +
               "  <edge id=\"C" + o + "\" from=\"C\" to=\"" + o + "\" numLanes=\"1\" speed=\"13.89\"/>\n";
    write(d + "/x.edg.xml", edges + "</edges>\n");
    // Cars from the west and the south every 6 s meet at the signal: some stop at red, all cross on green.
    std::string routes = R"(<routes>
  <vType id="car" length="5.00" width="2.00" height="1.50" sigma="0"/>
  <vType id="walker" vClass="pedestrian" length="0.80" width="0.60"/>
  <person id="p0" type="walker" depart="0"><walk edges="WC CN"/></person>
)";
    for (int k = 0; k < 12; ++k) {
      routes += "  <vehicle id=\"w" + std::to_string(k) + "\" type=\"car\" depart=\"" + std::to_string(6 * k) +
                "\" departSpeed=\"max\"><route edges=\"WC CE\"/></vehicle>\n";
      routes += "  <vehicle id=\"s" + std::to_string(k) + "\" type=\"car\" depart=\"" + std::to_string(6 * k + 1) +
                "\" departSpeed=\"max\"><route edges=\"SC CN\"/></vehicle>\n";
    }
    routes += "</routes>\n";  // (departures in time order: SUMO reads route files incrementally)
    write(d + "/x.rou.xml", routes);
    write(d + "/signals.add.xml",
          R"(<additional><timedEvent type="SaveTLSSwitchStates" dest="signals.xml"/></additional>)");
    ok_ = run({"netconvert", "--node-files", "x.nod.xml", "--edge-files", "x.edg.xml", "--sidewalks.guess",
               "--crossings.guess", "--walkingareas", "--tls.default-type", "static", "-o", "x.net.xml"},
              d) == 0 &&
          run({"sumo", "-n", "x.net.xml", "-r", "x.rou.xml", "-a", "signals.add.xml", "--step-length", "0.1", "-e",
               "150", "--fcd-output", "fcd.xml", "--fcd-output.attributes", "x,y,angle,speed,type,pos,lane",
               "--no-step-log"},
              d) == 0;
  }
  static void TearDownTestSuite() {
    if (dir_) fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (!dir_) GTEST_SKIP() << "sumo or netconvert is not installed";
    ASSERT_TRUE(ok_) << "netconvert or sumo failed in " << *dir_ << ": " << slurp(*dir_ + "/netconvert.err")
                     << slurp(*dir_ + "/sumo.err");
    net_text_ = slurp(*dir_ + "/x.net.xml");
    fcd_text_ = slurp(*dir_ + "/fcd.xml");
    auto net = parse_sumo_net(net_text_, "x.net.xml");
    ASSERT_TRUE(net.ok()) << net.status();
    net_ = std::move(*net);
    map_ = build_sumo_map(net_);
  }

  // Every vehicle sample as SUMO states it: time, id, front position, lane and position along it.
  struct Sample {
    double time;
    std::string id, lane;
    double pos, speed;
  };
  std::vector<Sample> samples() const {
    std::vector<Sample> out;
    XmlScanner x(fcd_text_, "fcd.xml");
    double t = 0;
    while (*x.next()) {
      if (x.is_start() && x.name() == "timestep") t = *x.number("time");
      if (x.is_start() && x.name() == "vehicle")
        out.push_back({t, x.get("id"), x.get("lane"), *x.number("pos"), *x.number("speed")});
    }
    return out;
  }

  static std::string* dir_;
  static bool ok_;
  std::string net_text_, fcd_text_;
  SumoNet net_;
  SumoMap map_;
};
std::string* SumoRunTest::dir_ = nullptr;
bool SumoRunTest::ok_ = false;

TEST_F(SumoRunTest, BoxCentresAndHeadingsAgreeWithSumoLanePositions) {
  const AgentKinds kinds = {{"car", {ObjectType::vehicle, 5.0f, 2.0f, 1.5f}},
                            {"walker", {ObjectType::pedestrian, 0.8f, 0.6f, 1.7f}}};
  auto rec = parse_fcd(fcd_text_, "fcd.xml", kinds, {{"p0", "walker"}}, 0.1);
  ASSERT_TRUE(rec.ok()) << rec.status();
  std::map<std::string, const FcdTrack*> by_id;
  for (const FcdTrack& t : rec->tracks) by_id[t.id] = &t;
  ASSERT_TRUE(by_id.count("p0"));
  EXPECT_EQ(by_id["p0"]->kind.type, ObjectType::pedestrian);
  int checked = 0;
  for (const Sample& s : samples()) {
    if (s.lane.empty() || s.lane[0] == ':' || s.pos < 5.0) continue;  // normal lanes, whole car on the lane
    const SumoLane& lane = net_.lanes[net_.find_lane(s.lane)];
    // SUMO's lane position is the front bumper: the centre is half a length (2.5 m) back along the lane.
    const Vec2 want = point_along(lane.shape, s.pos - 2.5);
    const FcdState* got = by_id.at(s.id)->at(rec->frame_of(s.time));
    ASSERT_NE(got, nullptr);
    EXPECT_NEAR(got->x, want.x, 0.02) << s.id << " at " << s.time;
    EXPECT_NEAR(got->y, want.y, 0.02) << s.id << " at " << s.time;
    // The heading is the lane's direction (these lanes are straight).
    const Vec2 dir = lane.shape.back() - lane.shape.front();
    EXPECT_NEAR(std::remainder(got->heading - std::atan2(dir.y, dir.x), 2 * kPi), 0.0, 0.01) << s.id;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
}

TEST_F(SumoRunTest, SignalStatesMatchWhatCarsDo) {
  auto signals = parse_signal_switches(slurp(*dir_ + "/signals.xml"), "signals.xml");
  ASSERT_TRUE(signals.ok()) << signals.status();
  ASSERT_GT(signals->num_lights(), 0u);
  std::map<int64_t, const SignalLink*> link_of_lane;
  for (const SignalLink& l : map_.signal_links) link_of_lane[l.lane] = &l;
  auto state = [&](const std::string& internal_lane, double t) {
    const int64_t f = map_.feature_of_lane[net_.find_lane(internal_lane)];
    const SignalLink* l = link_of_lane.at(f);
    const std::string* s = signals->state_at(l->tl, t);
    return s ? signal_state_from_sumo((*s)[l->link_index], l->dir) : SignalState::unknown;
  };
  // For each car: the internal lane it crossed by, when it entered it, and when it waited at the stop line.
  const std::vector<Sample> all = samples();
  std::map<std::string, std::string> via;
  std::map<std::string, double> entered;
  std::map<std::string, std::vector<double>> waited;
  for (const Sample& s : all) {
    if (s.lane.starts_with(":C_") && !via.count(s.id)) {
      via[s.id] = s.lane;
      entered[s.id] = s.time;
    }
    const int li = net_.find_lane(s.lane);
    if (li >= 0 && s.lane[0] != ':' && net_.lanes[li].length - s.pos < 10 && s.speed < 0.1 &&
        net_.edges[net_.lanes[li].edge].to == "C")
      waited[s.id].push_back(s.time);
  }
  ASSERT_GE(via.size(), 20u);
  int stops = 0;
  for (const auto& [car, lane] : via) {
    const SignalState at_entry = state(lane, entered[car]);
    EXPECT_TRUE(at_entry == SignalState::go || at_entry == SignalState::caution) << car << " entered on " << static_cast<int>(at_entry);
    for (double t : waited[car]) {
      // Standing at the stop line: red or yellow, or green for less than 2 s (the driver is starting off).
      const SignalState s = state(lane, t), before = state(lane, t - 2.0);
      EXPECT_TRUE(s == SignalState::stop || s == SignalState::caution || before == SignalState::stop)
          << car << " waited at " << t;
      ++stops;
    }
  }
  EXPECT_GT(stops, 10) << "no car waited at a red light: the test shows nothing";
}

TEST_F(SumoRunTest, CrossingsBecomeCrosswalks) {
  int crossings = 0;
  for (const SumoLane& l : net_.lanes) crossings += net_.edges[l.edge].function == SumoEdgeFunction::crossing;
  ASSERT_EQ(crossings, 4);  // one over each arm of the crossroads
  int crosswalks = 0;
  for (const MapFeature& f : map_.features) {
    if (f.kind != MapFeatureKind::crosswalk) continue;
    ++crosswalks;
    ASSERT_EQ(f.points.size(), 4u);
    // A rectangle: opposite sides equal, a right angle at each corner.
    const Vec2 a{f.points[0].x, f.points[0].y}, b{f.points[1].x, f.points[1].y}, c{f.points[2].x, f.points[2].y};
    EXPECT_NEAR(dot(b - a, c - b), 0.0, 1e-6);
    EXPECT_GT(distance(b, c), 1.0);  // the crossing's width
  }
  EXPECT_EQ(crosswalks, crossings);
}

}  // namespace
}  // namespace ss
