#include "tools/dataset/demand.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace ss::dataset {
namespace {

struct DensityRange {
  double car_lo, car_hi;
};

// Car departures per hour per km of lane. Measured here (2-lane grids and spiders carry ~250 before windows with
// collisions and teleports multiply); random networks (1-lane roads, many unsignalised junctions) and OSM cut-outs
// (dead ends at the box border) jam earlier.
DensityRange car_density(const std::string& kind) {
  if (kind == "grid") return {100, 250};
  if (kind == "spider") return {100, 220};
  if (kind == "rand") return {60, 150};
  return {60, 160};
}

// Driving style: acceleration, braking, imperfection, reaction time, gaps, speed keeping and lane changing.
std::string driver(Rng& r) {
  return absl::StrFormat(
      "accel=\"%.2f\" decel=\"%.2f\" emergencyDecel=\"9\" sigma=\"%.2f\" tau=\"%.2f\" minGap=\"%.2f\" "
      "speedFactor=\"normc(%.2f,0.1,0.6,1.5)\" lcStrategic=\"%.2f\" lcCooperative=\"%.2f\" lcSpeedGain=\"%.2f\"",
      r.uniform(1.8, 3.2), r.uniform(3.5, 5.0), r.uniform(0.2, 0.6), r.uniform(0.8, 1.6), r.uniform(1.5, 3.0),
      r.uniform(0.95, 1.15), r.uniform(0.5, 2.0), r.uniform(0.5, 1.0), r.uniform(0.5, 2.0));
}

}  // namespace

VehicleTypes make_vehicle_types(Rng& rng) {
  VehicleTypes v;
  // Box sizes follow WOMD's (the perception boxes include mirrors): cars ~4.6 x 2.1 m, cyclists ~1.9 x 0.8 m.
  // Pedestrians (WOMD ~0.9 x 0.8 m) stay within SUMO's sidewalk stripe width of 0.65 m, wider ones collide.
  auto vtype = [&](std::string* xml, const std::string& id, const std::string& vclass, ObjectType type, double length,
                   double width, double height, double probability, const std::string& extra) {
    absl::StrAppend(xml, absl::StrFormat("    <vType id=\"%s\" vClass=\"%s\" length=\"%.2f\" width=\"%.2f\" "
                                         "height=\"%.2f\" probability=\"%.3f\" %s/>\n",
                                         id, vclass, length, width, height, probability, extra));
    // The kinds table uses the values as written (2 decimals), so boxes match what SUMO simulates.
    v.kinds[id] = {type, static_cast<float>(std::stod(absl::StrFormat("%.2f", length))),
                   static_cast<float>(std::stod(absl::StrFormat("%.2f", width))),
                   static_cast<float>(std::stod(absl::StrFormat("%.2f", height)))};
  };
  std::string& veh = v.vehicles_xml;
  veh = "<additional>\n  <vTypeDistribution id=\"cars\">\n";
  for (int i = 0; i < 12; ++i)
    vtype(&veh, absl::StrCat("car", i), "passenger", ObjectType::vehicle, rng.uniform(4.2, 5.0), rng.uniform(1.9, 2.1),
          rng.uniform(1.4, 1.6), 0.06, driver(rng));
  for (int i = 0; i < 5; ++i)
    vtype(&veh, absl::StrCat("suv", i), "passenger", ObjectType::vehicle, rng.uniform(4.7, 5.6), rng.uniform(2.0, 2.25),
          rng.uniform(1.7, 1.95), 0.035, driver(rng));
  for (int i = 0; i < 3; ++i)
    vtype(&veh, absl::StrCat("van", i), "delivery", ObjectType::vehicle, rng.uniform(5.5, 8.0), rng.uniform(2.1, 2.5),
          rng.uniform(2.2, 3.3), 0.02, "maxSpeed=\"25\" " + driver(rng));
  vtype(&veh, "bus0", "bus", ObjectType::vehicle, 12.0, 2.55, 3.2, 0.01, "maxSpeed=\"20\" " + driver(rng));
  veh += "  </vTypeDistribution>\n  <vTypeDistribution id=\"bikes\">\n";
  for (int i = 0; i < 4; ++i)
    vtype(&veh, absl::StrCat("bike", i), "bicycle", ObjectType::cyclist, rng.uniform(1.7, 2.0), rng.uniform(0.75, 0.95),
          1.7, 0.25,
          absl::StrFormat("maxSpeed=\"%.1f\" speedFactor=\"normc(1,0.15,0.5,1.5)\" minGap=\"0.5\" sigma=\"0.5\" "
                          "latAlignment=\"right\"",
                          rng.uniform(4.5, 7.5)));
  veh += "  </vTypeDistribution>\n</additional>\n";

  std::string& ped = v.pedestrians_xml;
  ped = "<additional>\n  <vTypeDistribution id=\"peds\">\n";
  for (int i = 0; i < 4; ++i)
    vtype(&ped, absl::StrCat("ped", i), "pedestrian", ObjectType::pedestrian, rng.uniform(0.6, 0.9),
          rng.uniform(0.5, 0.65), rng.uniform(1.5, 1.9), 0.25, "speedFactor=\"normc(1,0.15,0.5,1.6)\"");
  ped += "  </vTypeDistribution>\n</additional>\n";
  return v;
}

std::string assign_person_types(const std::string& trips_xml, const AgentKinds& kinds, Rng& rng, AgentTypes* types) {
  std::vector<std::string> peds;
  for (const auto& [id, kind] : kinds)
    if (kind.type == ObjectType::pedestrian) peds.push_back(id);
  std::sort(peds.begin(), peds.end());  // the map's order is not fixed; the draw must be
  std::string out;
  out.reserve(trips_xml.size());
  size_t pos = 0;
  const std::string from = "type=\"peds\"";
  while (true) {
    const size_t tag = trips_xml.find("<person ", pos);
    const size_t close = tag == std::string::npos ? tag : trips_xml.find('>', tag);
    if (close == std::string::npos || peds.empty()) break;
    std::string head = trips_xml.substr(tag, close - tag);
    const size_t id_at = head.find(" id=\"");
    const size_t at = head.find(from);
    if (id_at != std::string::npos && at != std::string::npos) {
      const std::string id = head.substr(id_at + 5, head.find('"', id_at + 5) - id_at - 5);
      const std::string& type = rng.pick(peds);
      head.replace(at, from.size(), "type=\"" + type + "\"");
      (*types)[id] = type;
    }
    out.append(trips_xml, pos, tag - pos);
    out += head;
    pos = close;
  }
  out.append(trips_xml, pos);
  return out;
}

absl::StatusOr<Demand> build_demand(const std::string& network_kind, const std::string& net_file, Rng& rng,
                                    int sumo_seed, double end, JobContext& job) {
  Demand d;
  VehicleTypes types = make_vehicle_types(rng);
  if (auto st = job.write("vehicle types", "vehicles.add.xml", types.vehicles_xml); !st.ok()) return st;
  if (auto st = job.write("vehicle types", "pedestrians.add.xml", types.pedestrians_xml); !st.ok()) return st;
  d.kinds = std::move(types.kinds);
  d.additional = {job.path("vehicles.add.xml"), job.path("pedestrians.add.xml")};

  const DensityRange range = car_density(network_kind);
  const double cars = rng.uniform(range.car_lo, range.car_hi);
  // WOMD has ~5 pedestrians and well under one cyclist per vehicle-dense scenario; SUMO's pedestrians also crowd
  // the sidewalks of a small network quickly.
  const double bikes = rng.uniform(2, 10);
  const double peds = rng.uniform(10, 45);
  const std::string end_s = absl::StrFormat("%.1f", end);
  auto trips = [&](const std::string& step, const std::string& out, std::vector<std::string> extra) -> absl::Status {
    std::vector<std::string> args = {job.tools().random_trips, "-n", net_file, "-o", out, "-b", "0", "-e", end_s};
    args.insert(args.end(), extra.begin(), extra.end());
    if (auto st = job.run(step, job.tools().python, args); !st.ok()) return st;
    d.route_files.push_back(job.path(out));
    return absl::OkStatus();
  };
  // Trips are routed by sumo at departure (unroutable ones are skipped with --ignore-route-errors), which is much
  // cheaper than randomTrips --validate running duarouter; sumo loads the vType files itself.
  if (auto st = trips("car trips", "cars.trips.xml",
                      {"--insertion-density", absl::StrFormat("%.1f", cars), "--fringe-factor", "10",
                       "--min-distance", "300", "--vclass", "passenger", "--prefix", "v", "--seed",
                       std::to_string(sumo_seed), "--trip-attributes",
                       "type=\"cars\" departLane=\"best\" departSpeed=\"max\""});
      !st.ok())
    return st;
  if (auto st = trips("bicycle trips", "bikes.trips.xml",
                      {"--insertion-density", absl::StrFormat("%.1f", bikes), "--fringe-factor", "5",
                       "--min-distance", "200", "--vclass", "bicycle", "--prefix", "b", "--seed",
                       std::to_string(sumo_seed + 1), "--trip-attributes",
                       "type=\"bikes\" departLane=\"best\" departSpeed=\"max\""});
      !st.ok())
    return st;
  if (auto st = trips("pedestrian trips", "pedestrians.trips.xml",
                      {"--insertion-density", absl::StrFormat("%.1f", peds), "--pedestrians", "--min-distance", "100",
                       "--max-distance", "400", "--prefix", "p", "--seed", std::to_string(sumo_seed + 2),
                       "--trip-attributes", "type=\"peds\""});
      !st.ok())
    return st;
  auto ped_trips = job.read("pedestrian trips", "pedestrians.trips.xml");
  if (!ped_trips.ok()) return ped_trips.status();
  if (auto st = job.write("pedestrian trips", "pedestrians.trips.xml",
                          assign_person_types(*ped_trips, d.kinds, rng, &d.person_types));
      !st.ok())
    return st;
  d.description = absl::StrFormat("cars %.0f, bicycles %.0f, pedestrians %.0f departures/h/km", cars, bikes, peds);
  return d;
}

}  // namespace ss::dataset
