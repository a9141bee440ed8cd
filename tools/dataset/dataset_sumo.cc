// scenestreamer dataset sumo --out DIR --scenarios N --seed S [--networks grid,spider,rand,osm] [--radius 100] ...
// Runs generation jobs (network, demand, SUMO run, windows) in parallel, takes their scenarios in job order until N,
// writes them into TFRecord shards (each validated once written) and a MANIFEST. Job i's seed depends only on S and
// i, so the dataset is the same bytes whatever the number of workers.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "engine/base/rng.h"
#include "engine/io/file_io.h"
#include "engine/io/json_text.h"
#include "nlohmann/json.hpp"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/dataset/dataset_commands.h"
#include "tools/dataset/job.h"
#include "tools/dataset/job_context.h"
#include "tools/dataset/network.h"
#include "engine/base/ordered_pool.h"
#include "tools/dataset/shard_writer.h"
#include "tools/dataset/subprocess.h"
#include "tools/dataset/sumo_tools.h"
#include "tools/shared_flags.h"

ABSL_FLAG(int, scenarios, 0, "scenarios to generate (required)");
ABSL_FLAG(std::string, networks, absl::StrJoin(ss::dataset::kNetworkKinds, ","),
          "network kinds, used in turn, from grid, spider, rand, osm");
// dataset_sumo_: render's --radius is its view.
ABSL_FLAG(double, dataset_sumo_radius, ss::WindowOptions{}.radius, "agents are tracked within M metres of the ego");
ABSL_FLAG(double, map_radius, 0, "map features within M metres of the ego; 0: --radius + 50");
ABSL_FLAG(int, workers, 0, "parallel SUMO jobs; 0: the number of hardware threads");
ABSL_FLAG(double, warmup, 240, "simulated seconds before recording");
ABSL_FLAG(double, record, 90, "recorded seconds per SUMO run, at least 9.1 (one window)");
ABSL_FLAG(int, egos_per_window, ss::WindowOptions{}.egos_per_window,
          "scenarios cut per 9.1 s window, around egos 100 m apart");
ABSL_FLAG(int, shard_size, 250, "scenarios per TFRecord shard");
ABSL_FLAG(std::string, sumo_bin, "", "directory of sumo, netgenerate, netconvert; default: PATH");
ABSL_FLAG(std::string, sumo_home, "/usr/share/sumo", "SUMO_HOME, for randomTrips.py and the OSM networks");
ABSL_FLAG(std::string, python, "/usr/bin/python3", "Python for randomTrips.py");
ABSL_FLAG(std::string, tmp, "", "where job directories are made; default: $TMPDIR or /tmp");
ABSL_FLAG(bool, keep_temp, false, "keep the job directories (for debugging)");
ABSL_FLAG(int, first_job, 0, "start at job K instead of 0 (to rerun the job an error names)");
ABSL_FLAG(bool, quiet, false, "no progress lines");

namespace ss::dataset {
namespace {

namespace fs = std::filesystem;

constexpr const char* kUsage =
    "usage: scenestreamer dataset sumo --out DIR --scenarios N --seed S [flags]\n"
    "  Generates N WOMD scenarios (9.1 s at 10 Hz, current frame 10) with SUMO into DIR/sumo.tfrecord-*-of-*\n"
    "  and DIR/MANIFEST (JSON: counts by type and network, seeds, shards, validation).\n";

// A job whose run yields no scenario (a gridlocked network, say) is normal now and then; this many in a row means
// the settings cannot work.
constexpr int kMaxEmptyJobsInARow = 20;

struct Options {
  std::string out;
  int scenarios = 0;
  uint64_t seed = 0;
  std::vector<std::string> networks = kNetworkKinds;
  int workers = 1;
  int shard_size = 250;
  double warmup = 240, record = 90;
  WindowOptions windows;
  std::string sumo_bin, sumo_home = "/usr/share/sumo", python = "/usr/bin/python3", tmp;
  bool keep_temp = false, quiet = false;
  int first_job = 0;
};

absl::Status bad_flag(const std::string& flag, const std::string& want) {
  return absl::InvalidArgumentError(absl::StrCat("--", flag, ": ", want));
}

absl::StatusOr<Options> parse_options(const cli::CommandLine& line) {
  Options o;
  if (!line.has(FLAGS_out)) return absl::InvalidArgumentError("--out is required");
  if (!line.has(FLAGS_scenarios)) return absl::InvalidArgumentError("--scenarios is required");
  if (!line.has(FLAGS_seed)) return absl::InvalidArgumentError("--seed is required");
  o.out = absl::GetFlag(FLAGS_out);
  o.scenarios = absl::GetFlag(FLAGS_scenarios);
  if (o.scenarios < 1) return bad_flag("scenarios", "want a positive integer");
  o.seed = absl::GetFlag(FLAGS_seed);
  o.networks.clear();
  for (absl::string_view n : absl::StrSplit(absl::GetFlag(FLAGS_networks), ',')) {
    const std::string name(n);
    if (std::find(kNetworkKinds.begin(), kNetworkKinds.end(), name) == kNetworkKinds.end())
      return bad_flag("networks", absl::StrCat("unknown kind \"", name, "\" (grid, spider, rand, osm)"));
    o.networks.push_back(name);
  }
  const unsigned hw = std::thread::hardware_concurrency();
  o.workers = absl::GetFlag(FLAGS_workers);
  if (o.workers < 0) return bad_flag("workers", "want a positive integer, or 0 for the hardware's threads");
  if (o.workers == 0) o.workers = hw ? static_cast<int>(hw) : 1;
  o.shard_size = absl::GetFlag(FLAGS_shard_size);
  if (o.shard_size < 1) return bad_flag("shard-size", "want a positive integer");
  o.windows.radius = absl::GetFlag(FLAGS_dataset_sumo_radius);
  o.windows.map_radius = absl::GetFlag(FLAGS_map_radius);
  if (o.windows.map_radius == 0) o.windows.map_radius = o.windows.radius + 50;
  o.warmup = absl::GetFlag(FLAGS_warmup);
  o.record = absl::GetFlag(FLAGS_record);
  for (auto [flag, v] : {std::pair<const char*, double>{"radius", o.windows.radius}, {"map-radius", o.windows.map_radius},
                         {"warmup", o.warmup}, {"record", o.record}})
    if (!(v > 0) || !std::isfinite(v)) return bad_flag(flag, "want a positive number");
  if (o.record < 9.1) return bad_flag("record", "want at least 9.1 s (one window)");
  o.windows.egos_per_window = absl::GetFlag(FLAGS_egos_per_window);
  if (o.windows.egos_per_window < 1) return bad_flag("egos-per-window", "want a positive integer");
  o.sumo_bin = absl::GetFlag(FLAGS_sumo_bin);
  o.sumo_home = absl::GetFlag(FLAGS_sumo_home);
  o.python = absl::GetFlag(FLAGS_python);
  const char* tmpdir = std::getenv("TMPDIR");
  o.tmp = line.has(FLAGS_tmp) ? absl::GetFlag(FLAGS_tmp) : tmpdir && *tmpdir ? tmpdir : "/tmp";
  o.keep_temp = absl::GetFlag(FLAGS_keep_temp);
  o.first_job = absl::GetFlag(FLAGS_first_job);
  if (o.first_job < 0) return bad_flag("first-job", "want a non-negative integer");
  o.quiet = absl::GetFlag(FLAGS_quiet);
  return o;
}

// The first line of `sumo --version`, for the manifest.
std::string sumo_version(const SumoTools& tools, const std::string& tmp) {
  auto dir = TempDir::create(tmp, "scenestreamer-sumo-version-");
  if (!dir.ok()) return "";
  Command c{tools.sumo, {"--version"}, dir->path(), tools.env(), dir->path() + "/out", dir->path() + "/err"};
  auto r = run_command(c);
  if (!r.ok() || !r->ok()) return "";
  std::ifstream in(dir->path() + "/out");
  std::string line;
  std::getline(in, line);
  return line;
}

absl::Status check_out_dir(const std::string& out) {
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return absl::FailedPreconditionError(absl::StrCat("cannot create --out ", out, ": ", ec.message()));
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name == "MANIFEST" || name.starts_with("sumo.tfrecord-"))
      return absl::FailedPreconditionError(absl::StrCat(
          out, " already holds a generated dataset (", name, "); choose another --out or delete it first"));
  }
  return absl::OkStatus();
}

nlohmann::ordered_json fidelity_summary(const TokenizationFidelity& f, int validated) {
  nlohmann::ordered_json j;
  j["scenarios_read_back_and_tokenized"] = validated;
  j["motion_ace_mean_m"] = f.ace.mean();
  j["motion_ace_max_m"] = f.ace.max;
  nlohmann::ordered_json by_type = nlohmann::ordered_json::object();
  for (int t = 0; t < kNumModelTypes; ++t) by_type[model_type_name(t)] = f.ace_by_type[t].mean();
  j["motion_ace_mean_by_type_m"] = by_type;
  j["state_samples"] = f.state_samples;
  j["state_without_anchor"] = f.state_without_anchor;
  return j;
}

int run(const Options& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const char* path_env = std::getenv("PATH");
  auto tools = find_sumo_tools(o.sumo_bin, path_env ? path_env : "", o.sumo_home, o.python);
  if (!tools.ok()) {
    spdlog::error("dataset sumo: step check: {}", std::string(tools.status().message()));
    return 1;
  }
  if (auto st = check_out_dir(o.out); !st.ok()) {
    spdlog::error("dataset sumo: {}", std::string(st.message()));
    return 1;
  }
  const std::string version = sumo_version(*tools, o.tmp);

  auto spec_of = [&](int index) {
    JobSpec s;
    s.index = index;
    s.dataset_seed = o.seed;
    s.seed = mix_seed(o.seed, static_cast<uint64_t>(index));
    s.network = o.networks[index % o.networks.size()];
    s.warmup = o.warmup;
    s.record = o.record;
    s.windows = o.windows;
    s.id_prefix = absl::StrCat("sumo_s", o.seed, "_j", index);
    s.temp_root = o.tmp;
    s.keep_temp = o.keep_temp;
    return s;
  };

  ShardWriter writer(o.out, o.scenarios, o.shard_size);
  nlohmann::ordered_json jobs = nlohmann::ordered_json::array();
  std::map<std::string, int> tracks_by_type, scenarios_by_network;
  std::map<std::string, double> seconds;
  int total = 0, empty_in_a_row = 0, dropped_collision = 0, dropped_teleport = 0, dropped_implausible = 0;
  {
    OrderedPool<JobResult> pool(o.workers, 4 * o.workers + 2, [&](int i) { return run_job(spec_of(o.first_job + i), *tools); });
    while (total < o.scenarios) {
      auto r = pool.next();
      if (!r.ok()) {
        pool.stop();
        spdlog::error("dataset sumo: {}", std::string(r.status().message()));
        return 1;
      }
      const int take = std::min<int>(static_cast<int>(r->records.size()), o.scenarios - total);
      for (int i = 0; i < take; ++i)
        for (const auto& [type, n] : r->tracks_by_type[i]) tracks_by_type[type] += n;
      for (int i = 0; i < take; ++i) {
        if (auto st = writer.add(std::move(r->records[i]), r->ids[i], r->fidelity[i]); !st.ok()) {
          pool.stop();
          spdlog::error("dataset sumo: {}", std::string(st.message()));
          return 1;
        }
      }
      total += take;
      scenarios_by_network[r->network] += take;
      dropped_collision += r->dropped_collision;
      dropped_teleport += r->dropped_teleport;
      dropped_implausible += r->dropped_implausible;
      for (const auto& [step, s] : r->seconds) seconds[step] += s;
      jobs.push_back({{"index", r->index}, {"seed", r->seed}, {"sumo_seed", r->sumo_seed}, {"network", r->network},
                      {"network_description", r->network_description}, {"demand", r->demand_description},
                      {"windows", r->windows}, {"scenarios", r->records.size()}, {"scenarios_used", take},
                      {"dropped_collision", r->dropped_collision}, {"dropped_teleport", r->dropped_teleport},
                      {"dropped_implausible", r->dropped_implausible}, {"failed_attempts", r->failed_attempts},
                      {"sumo_collisions", r->sumo_collisions}, {"sumo_teleports", r->sumo_teleports}});
      if (!o.quiet) {
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        double job_seconds = 0;
        for (const auto& [step, s] : r->seconds) job_seconds += s;
        spdlog::info("job {} {:<6} {:3} scenarios ({} dropped) in {:.1f} s (sumo {:.1f} s)  total {}/{}  {:.0f} s  {}{}",
                     r->index, r->network, r->records.size(), r->dropped_collision + r->dropped_teleport + r->dropped_implausible,
                     job_seconds, r->seconds.count("sumo") ? r->seconds.at("sumo") : 0.0, total, o.scenarios, elapsed,
                     r->network_description, r->kept_dir.empty() ? "" : " [" + r->kept_dir + "]");
      }
      empty_in_a_row = r->records.empty() ? empty_in_a_row + 1 : 0;
      if (empty_in_a_row >= kMaxEmptyJobsInARow) {
        pool.stop();
        spdlog::error("dataset sumo: {} jobs in a row gave no scenario (last: job {}, seed {}, network {}): no moving "
                      "vehicle stays in the network for 9.1 s, or every window holds a collision, teleport or implausible "
                      "motion",
                      empty_in_a_row, r->index, r->seed, r->network);
        return 1;
      }
    }
    pool.stop();
  }
  if (auto st = writer.finish(); !st.ok()) {
    spdlog::error("dataset sumo: {}", std::string(st.message()));
    return 1;
  }

  // Only what determines the data goes in: the same seed gives the same MANIFEST whatever the workers.
  nlohmann::ordered_json m;
  m["generator"] = "scenestreamer dataset sumo";
  m["format"] = "TFRecord of waymo.open_dataset.Scenario protos";
  m["sumo_version"] = version;
  m["seed"] = o.seed;
  m["scenarios"] = total;
  m["frames"] = o.windows.frames;
  m["current_time_index"] = o.windows.current_frame;
  m["step_seconds"] = 0.1;
  m["options"] = {{"networks", o.networks},     {"radius", o.windows.radius}, {"first_job", o.first_job},
                  {"map_radius", o.windows.map_radius}, {"warmup_seconds", o.warmup},
                  {"record_seconds", o.record}, {"egos_per_window", o.windows.egos_per_window},
                  {"window_stride_seconds", o.windows.stride}, {"shard_size", o.shard_size}};
  m["tracks_by_type"] = tracks_by_type;
  m["scenarios_by_network"] = scenarios_by_network;
  m["dropped_windows"] = {{"collision", dropped_collision}, {"teleport", dropped_teleport},
                          {"implausible_motion", dropped_implausible}};
  m["shards"] = writer.shard_list();
  m["validation"] = fidelity_summary(writer.fidelity(), writer.validated());
  m["jobs"] = jobs;
  const std::string manifest = o.out + "/MANIFEST";
  if (auto st = file_write_atomically(manifest, json_text(m) + "\n"); !st.ok()) {
    spdlog::error("dataset sumo: {}", std::string(st.message()));
    return 1;
  }
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("wrote %d scenarios in %d shards to %s in %.1f s (%.2f scenarios/s, %d workers)\n", total,
              writer.shards(), o.out.c_str(), elapsed, total / elapsed, o.workers);
  std::printf("validated %d: read back and tokenized, motion ACE mean %.3f m\n", writer.validated(),
              writer.fidelity().ace.mean());
  std::string steps;
  for (const auto& [step, s] : seconds) absl::StrAppend(&steps, steps.empty() ? "" : ", ", step, " ", static_cast<int>(s), " s");
  std::printf("job time by step (summed over workers): %s\n", steps.c_str());
  return 0;
}

}  // namespace

int sumo_main(int argc, char** argv) {
  const cli::Command command{"scenestreamer dataset sumo", kUsage, __FILE__,
                             {cli::flag(FLAGS_out), cli::flag(FLAGS_seed)}};
  cli::CommandLine line;
  if (auto exit_code = cli::parse_command(command, argc, argv, &line)) return *exit_code;
  auto o = parse_options(line);
  if (!o.ok()) return cli::usage_error(command, o.status().message());
  return run(*o);
}

}  // namespace ss::dataset
