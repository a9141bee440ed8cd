#include "tools/dataset/job.h"

#include <chrono>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "offline/dataset/dataset_rng.h"
#include "offline/dataset/sumo_events.h"
#include "offline/dataset/sumo_fcd.h"
#include "offline/dataset/sumo_map.h"
#include "offline/dataset/sumo_net.h"
#include "engine/map/focus.h"
#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/scenario/womd_proto.h"
#include "tools/dataset/demand.h"
#include "tools/dataset/job_context.h"
#include "tools/dataset/network.h"

namespace ss::dataset {
namespace {

constexpr double kStep = 0.1;  // 10 Hz, WOMD's rate

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  }

 private:
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

std::string join(const std::vector<std::string>& v, const std::string& sep) {
  std::string out;
  for (const std::string& s : v) absl::StrAppend(&out, out.empty() ? "" : sep, s);
  return out;
}

absl::Status simulate(const JobSpec& spec, int seed, const std::string& net, const Demand& demand, JobContext& job) {
  // SaveTLSSwitchStates logs each light's state whenever it switches: the signal timeline of the run.
  if (auto st = job.write("sumo", "signals.add.xml",
                          "<additional>\n  <timedEvent type=\"SaveTLSSwitchStates\" dest=\"signals.xml\"/>\n"
                          "</additional>\n");
      !st.ok())
    return st;
  std::vector<std::string> additional = demand.additional;
  additional.push_back(job.path("signals.add.xml"));
  const std::vector<std::string> args = {
      "-n", net, "-a", join(additional, ","), "-r", join(demand.route_files, ","),
      "--step-length", absl::StrFormat("%.1f", kStep), "-b", "0", "-e", absl::StrFormat("%.1f", spec.warmup + spec.record),
      "--seed", std::to_string(seed),
      "--device.fcd.begin", absl::StrFormat("%.1f", spec.warmup), "--fcd-output", "fcd.xml",
      "--fcd-output.attributes", "x,y,angle,type,speed",
      // Lane changes over 3 s instead of SUMO's default 3.5 m jump within one step.
      "--lanechange.duration", "3",
      "--time-to-teleport", "120", "--ignore-route-errors",
      // Collisions are reported (and the windows holding them dropped), not resolved by removing vehicles.
      "--collision.check-junctions", "--collision.action", "warn", "--collision-output", "collisions.xml",
      "--no-step-log", "--duration-log.disable",
      "--xml-validation", "never", "--xml-validation.net", "never", "--xml-validation.routes", "never"};
  return job.run("sumo", job.tools().sumo, args);
}

}  // namespace

int sumo_seed_of(uint64_t job_seed) { return static_cast<int>(job_seed % 2000000000ull); }

absl::StatusOr<JobResult> run_attempt(const JobSpec& spec, int attempt, const SumoTools& tools) {
  JobResult r;
  r.index = spec.index;
  r.seed = spec.seed;
  r.network = spec.network;
  r.sumo_seed = sumo_seed_of(spec.seed);
  const std::string label =
      absl::StrCat("job ", spec.index, " of seed ", spec.dataset_seed, " (network ", spec.network, ", job seed ",
                   spec.seed, ", SUMO seed ", r.sumo_seed, attempt > 1 ? absl::StrCat(", attempt ", attempt) : "", ")");
  auto dir = TempDir::create(spec.temp_root, absl::StrCat("scenestreamer-sumo-", spec.index, "-"));
  if (!dir.ok()) return absl::InternalError(absl::StrCat(label, ": ", dir.status().message()));
  if (spec.keep_temp) {
    dir->keep();
    r.kept_dir = dir->path();
  }
  JobContext job(tools, dir->path(), label);

  Rng network_rng = dataset_rng(mix_seed(spec.seed, 1)), demand_rng = dataset_rng(mix_seed(spec.seed, 2));
  auto net = build_network(spec.network, network_rng, r.sumo_seed, job);
  if (!net.ok()) return net.status();
  r.network_description = net->description;
  auto demand = build_demand(spec.network, net->file, demand_rng, r.sumo_seed, spec.warmup + spec.record, job);
  if (!demand.ok()) return demand.status();
  r.demand_description = demand->description;
  if (auto st = simulate(spec, r.sumo_seed, net->file, *demand, job); !st.ok()) return st;

  Stopwatch convert;
  auto net_xml = job.read("convert", "net.net.xml");
  if (!net_xml.ok()) return net_xml.status();
  auto sumo_net = parse_sumo_net(*net_xml, "net.net.xml");
  if (!sumo_net.ok()) return job.error("convert", std::string(sumo_net.status().message()));
  const SumoMap map = build_sumo_map(*sumo_net);
  auto fcd_xml = job.read("convert", "fcd.xml");
  if (!fcd_xml.ok()) return fcd_xml.status();
  auto fcd = parse_fcd(*fcd_xml, "fcd.xml", demand->kinds, demand->person_types, kStep);
  if (!fcd.ok()) return job.error("convert", std::string(fcd.status().message()));
  fcd_xml->clear();
  fcd_xml->shrink_to_fit();
  // SUMO writes no signal file for a network without traffic lights.
  auto signals_xml = sumo_net->traffic_lights.empty() ? absl::StatusOr<std::string>("") : job.read("convert", "signals.xml");
  if (!signals_xml.ok()) return signals_xml.status();
  auto signals = parse_signal_switches(*signals_xml, "signals.xml");
  if (!signals.ok()) return job.error("convert", std::string(signals.status().message()));
  auto collisions_xml = job.read("convert", "collisions.xml");
  if (!collisions_xml.ok()) return collisions_xml.status();
  auto incidents = parse_collisions(*collisions_xml, "collisions.xml");
  if (!incidents.ok()) return job.error("convert", std::string(incidents.status().message()));
  const std::vector<Incident> teleports = parse_teleports(job.stderr_of("sumo"));
  for (const Incident& i : *incidents) r.sumo_collisions += i.time >= spec.warmup ? 1 : 0;
  for (const Incident& i : teleports) r.sumo_teleports += i.time >= spec.warmup ? 1 : 0;
  incidents->insert(incidents->end(), teleports.begin(), teleports.end());

  WindowCut cut = cut_windows(map, *fcd, *signals, *incidents, spec.windows, mix_seed(spec.seed, 3), spec.id_prefix);
  r.windows = cut.windows;
  r.dropped_collision = cut.dropped_collision;
  r.dropped_teleport = cut.dropped_teleport;
  r.dropped_implausible = cut.dropped_implausible;
  for (const Scenario& s : cut.scenarios) {
    auto bytes = encode_womd_scenario(s, s.id);
    if (!bytes.ok()) return job.error("encode", std::string(bytes.status().message()));
    // Validation: the record decodes with the engine's reader to the same scenario, and tokenizes.
    auto back = scenario_from_womd_bytes(*bytes, s.id);
    if (!back.ok()) return job.error("validate", std::string(back.status().message()));
    if (!(*back == s)) return job.error("validate", absl::StrCat(s.id, " does not read back as written"));
    std::vector<MapSegment> segments = nearest_segments(segment_map(*back), scenario_focus(*back));
    const SegmentIndex index(segments);
    r.fidelity.push_back(measure_tokenization(*back, segments, index));
    const TokenizationFidelity& f = r.fidelity.back();
    if (!std::isfinite(f.ace.sum) || !std::isfinite(f.state_position_error.sum))
      return job.error("validate", absl::StrCat(s.id, ": tokenization gives a non-finite error"));
    r.records.push_back(std::move(*bytes));
    r.ids.push_back(s.id);
    std::map<std::string, int>& counts = r.tracks_by_type.emplace_back();
    for (const Track& t : s.tracks) ++counts[object_type_name(t.type)];
  }
  job.add_time("convert", convert.seconds());
  r.seconds = job.seconds();
  return r;
}

absl::StatusOr<JobResult> run_job(const JobSpec& spec, const SumoTools& tools) {
  std::vector<std::string> failures;
  JobSpec attempt_spec = spec;
  for (int attempt = 1;; ++attempt) {
    auto r = run_attempt(attempt_spec, attempt, tools);
    if (r.ok()) {
      r->failed_attempts = std::move(failures);
      return r;
    }
    if (r.status().code() != absl::StatusCode::kAborted || attempt == kJobAttempts) {
      if (failures.empty()) return r.status();
      return absl::Status(r.status().code(), absl::StrCat(r.status().message(), "\n(after ", failures.size(),
                                                          " failed attempts; the first: ", failures.front(), ")"));
    }
    failures.push_back(std::string(r.status().message().substr(0, r.status().message().find('\n'))));
    attempt_spec.seed = mix_seed(spec.seed, 1000 + attempt);
  }
}

}  // namespace ss::dataset
