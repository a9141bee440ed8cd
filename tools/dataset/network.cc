#include "tools/dataset/network.h"

#include <fstream>
#include <iterator>
#include <map>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "offline/dataset/sumo_net.h"
#include "offline/dataset/xml_scan.h"

namespace ss::dataset {
namespace {

std::string fmt(double v) { return absl::StrFormat("%.2f", v); }

// Gives each junction where three or more roads meet a control type; the others stay priority junctions.
// No allway_stop: Debian's SUMO 1.15 is built with assertions and aborts (MSLink.cpp:740) when vehicles and
// pedestrians meet at all-way stops. Stop signs come from priority_stop (the minor roads stop).
absl::StatusOr<std::string> mixed_junction_nodes(const std::string& nodes_xml, const std::string& edges_xml,
                                                 Rng& rng, std::map<std::string, int>* counts) {
  std::map<std::string, int> degree;  // edge ends at each node (a two-way road counts twice)
  XmlScanner e(edges_xml, "plain.edg.xml");
  while (true) {
    auto more = e.next();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if (!e.is_start() || e.name() != "edge") continue;
    ++degree[e.get("from")];
    ++degree[e.get("to")];
  }
  static const std::vector<std::string> kTypes = {"traffic_light", "priority", "priority_stop"};
  static const std::vector<double> kWeights = {0.55, 0.25, 0.20};
  std::string out = "<nodes>\n";
  XmlScanner n(nodes_xml, "plain.nod.xml");
  while (true) {
    auto more = n.next();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if (!n.is_start() || n.name() != "node") continue;
    const std::string id = n.get("id");
    const std::string type = degree[id] >= 5 ? kTypes[rng.weighted(kWeights)] : "priority";
    ++(*counts)[type];
    out += "  <node";
    for (const auto& a : n.attributes())
      if (a.name != "type" && a.name != "tl") absl::StrAppend(&out, " ", std::string(a.name), "=\"", std::string(a.value), "\"");
    absl::StrAppend(&out, " type=\"", type, "\"/>\n");
  }
  return out + "</nodes>\n";
}

absl::StatusOr<BuiltNetwork> generated_network(const std::string& kind, Rng& rng, int seed, JobContext& job) {
  BuiltNetwork net;
  const int lanes = std::vector<int>{1, 2, 2, 3}[rng.integer(0, 3)];
  const double speed_kmh = std::vector<double>{30, 40, 50, 50, 60, 70}[rng.integer(0, 5)];
  std::vector<std::string> args;
  std::string shape;
  if (kind == "grid") {
    const int nx = static_cast<int>(rng.integer(3, 5)), ny = static_cast<int>(rng.integer(3, 5));
    args = {"--grid", "--grid.x-number", std::to_string(nx), "--grid.y-number", std::to_string(ny),
            "--grid.x-length", fmt(rng.uniform(90, 180)), "--grid.y-length", fmt(rng.uniform(90, 180)),
            "--grid.attach-length", fmt(rng.uniform(60, 120)),
            "--perturb-x", fmt(rng.uniform(0, 8)), "--perturb-y", fmt(rng.uniform(0, 8))};
    if (lanes >= 2 && rng.chance(0.5)) args.push_back("--random-lanenumber");
    shape = absl::StrCat(nx, "x", ny);
  } else if (kind == "spider") {
    const int arms = static_cast<int>(rng.integer(4, 7)), circles = static_cast<int>(rng.integer(2, 4));
    args = {"--spider", "--spider.arm-number", std::to_string(arms), "--spider.circle-number", std::to_string(circles),
            "--spider.space-radius", fmt(rng.uniform(80, 140))};
    if (rng.chance(0.5)) args.push_back("--spider.omit-center");
    shape = absl::StrCat(arms, " arms x ", circles, " rings");
  } else {
    args = {"--rand", "--rand.iterations", std::to_string(rng.integer(40, 80)),
            "--rand.min-distance", fmt(rng.uniform(70, 100)), "--rand.max-distance", fmt(rng.uniform(150, 220)),
            "--rand.min-angle", "45", "--random-lanenumber"};
    if (rng.chance(0.5)) args.push_back("--rand.grid");
    shape = "random";
  }
  args.insert(args.end(), {"--seed", std::to_string(seed), "-L", std::to_string(lanes),
                           "--default.lanewidth", fmt(rng.uniform(3.0, 3.7)), "--default.speed", fmt(speed_kmh / 3.6),
                           "--plain-output-prefix", "plain", "-o", "netgenerate.net.xml", "--no-warnings"});
  if (auto st = job.run("netgenerate", job.tools().netgenerate, args); !st.ok()) return st;

  auto nodes = job.read("netgenerate", "plain.nod.xml");
  if (!nodes.ok()) return nodes.status();
  auto edges = job.read("netgenerate", "plain.edg.xml");
  if (!edges.ok()) return edges.status();
  std::map<std::string, int> types;
  auto mixed = mixed_junction_nodes(*nodes, *edges, rng, &types);
  if (!mixed.ok()) return job.error("junction types", std::string(mixed.status().message()));
  if (auto st = job.write("junction types", "mixed.nod.xml", *mixed); !st.ok()) return st;

  const std::string tls_type = rng.chance(0.5) ? "static" : "actuated";
  std::vector<std::string> nc = {
      "--node-files", "mixed.nod.xml", "--edge-files", "plain.edg.xml", "-o", "net.net.xml",
      "--sidewalks.guess", "--sidewalks.guess.max-speed", "20", "--crossings.guess",
      "--crossings.guess.speed-threshold", "20", "--walkingareas", "--no-turnarounds.except-deadend",
      "--tls.default-type", tls_type, "--junctions.corner-detail", "5", "--seed", std::to_string(seed),
      "--default.sidewalk-width", fmt(rng.uniform(1.5, 3.0)), "--xml-validation", "never", "--no-warnings"};
  const bool bike_lanes = rng.chance(0.3);
  if (bike_lanes) nc.push_back("--bikelanes.guess");
  if (auto st = job.run("netconvert", job.tools().netconvert, nc); !st.ok()) return st;

  // netconvert starts every signal program at offset 0.
  auto text = job.read("netconvert", "net.net.xml");
  if (!text.ok()) return text.status();
  const std::string shifted = with_tls_offsets(*text, [&](int) { return static_cast<int>(rng.integer(0, 89)); });
  if (auto st = job.write("signal offsets", "net.net.xml", shifted); !st.ok()) return st;

  net.file = job.path("net.net.xml");
  net.description = absl::StrCat(kind, " ", shape, ", ", lanes, " lane", lanes > 1 ? "s" : "", ", ", speed_kmh,
                                 " km/h, ", types["traffic_light"], " ", tls_type, " lights, ", types["priority_stop"],
                                 " stop junctions, ", types["priority"], " priority junctions",
                                 bike_lanes ? ", bike lanes" : "");
  return net;
}

absl::StatusOr<BuiltNetwork> osm_network(Rng& rng, int seed, JobContext& job) {
  const std::string rel = rng.pick(kOsmNetworks);
  const std::string source = job.tools().home + "/tools/" + rel;
  std::ifstream in(source, std::ios::binary);
  if (!in) return job.error("osm source", absl::StrCat("cannot read ", source, " (install the Debian package sumo-tools)"));
  const std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Centre the box on a junction: a signalised one half the time, so signals are common.
  std::vector<Vec2> lights, others;
  XmlScanner x(xml, source);
  while (true) {
    auto more = x.next();
    if (!more.ok()) return job.error("osm source", std::string(more.status().message()));
    if (!*more) break;
    if (!x.is_start() || x.name() != "junction") continue;
    const std::string type = x.get("type");
    if (type == "internal" || type == "dead_end") continue;
    auto jx = x.number("x"), jy = x.number("y");
    if (!jx.ok() || !jy.ok()) return job.error("osm source", std::string((jx.ok() ? jy : jx).status().message()));
    (type == "traffic_light" ? lights : others).push_back({*jx, *jy});
  }
  if (lights.empty() && others.empty()) return job.error("osm source", absl::StrCat(source, " has no junctions"));
  // A box can catch little road (a park's footpaths, one motorway ramp): then another box, up to a few times.
  constexpr int kAttempts = 5;
  constexpr double kMinRoadLength = 3000;  // metres of lanes cars may use
  for (int attempt = 1;; ++attempt) {
    const bool at_light = !lights.empty() && (others.empty() || rng.chance(0.5));
    const Vec2 c = at_light ? rng.pick(lights) : rng.pick(others);
    const double half = rng.uniform(350, 450);
    const std::string box =
        absl::StrCat(fmt(c.x - half), ",", fmt(c.y - half), ",", fmt(c.x + half), ",", fmt(c.y + half));
    // Only roads cars may use, and of them the largest connected piece; sidewalks and crossings are then guessed
    // where the map has none.
    std::vector<std::string> nc = {
        "--sumo-net-file", source, "-o", "net.net.xml", "--keep-edges.in-boundary", box,
        "--keep-edges.by-vclass", "passenger", "--keep-edges.components", "1",
        "--sidewalks.guess", "--sidewalks.guess.max-speed", "20", "--crossings.guess", "--walkingareas",
        "--junctions.corner-detail", "5", "--no-turnarounds.except-deadend", "--seed", std::to_string(seed),
        "--xml-validation", "never", "--xml-validation.net", "never", "--no-warnings"};
    if (auto st = job.run("netconvert", job.tools().netconvert, nc); !st.ok()) return st;
    auto text = job.read("netconvert", "net.net.xml");
    if (!text.ok()) return text.status();
    auto net = parse_sumo_net(*text, "net.net.xml");
    if (!net.ok()) return job.error("netconvert", std::string(net.status().message()));
    double road = 0;
    for (const SumoLane& l : net->lanes)
      if (l.use == SumoLaneUse::road && net->edges[l.edge].function == SumoEdgeFunction::normal) road += l.length;
    if (road >= kMinRoadLength) {
      BuiltNetwork built;
      built.file = job.path("net.net.xml");
      built.description = absl::StrCat("osm ", rel, " box ", box, at_light ? " around a signal" : "");
      return built;
    }
    if (attempt == kAttempts)
      return job.error("netconvert",
                       absl::StrCat(kAttempts, " boxes cut from ", rel, " held less than ", kMinRoadLength,
                                    " m of road; the last: ", box),
                       /*inputs_failed=*/true);
  }
}

}  // namespace

absl::StatusOr<BuiltNetwork> build_network(const std::string& kind, Rng& rng, int sumo_seed, JobContext& job) {
  if (kind == "osm") return osm_network(rng, sumo_seed, job);
  if (kind == "grid" || kind == "spider" || kind == "rand") return generated_network(kind, rng, sumo_seed, job);
  return job.error("network", absl::StrCat("unknown network kind \"", kind, "\" (grid, spider, rand, osm)"));
}

}  // namespace ss::dataset
