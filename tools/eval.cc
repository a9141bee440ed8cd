// scenestreamer eval --data FILE_OR_DIR... --model W --mode motion|full --rollouts K --seed S [--baseline cv|log]
//                   [--sdc model|log] --json OUT [--plots DIR] [--threads N] [--wosac-submission DIR]
// scenestreamer eval --data FILE_OR_DIR... --submission FILE_OR_DIR --json OUT
// scenestreamer eval --compare A.json B.json [--bootstrap N] [--seed S] [--json OUT]
#include <algorithm>
#include <cmath>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <thread>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "offline/eval/aggregate.h"
#include "offline/eval/evaluate.h"
#include "offline/eval/submission.h"
#include "engine/io/json_text.h"
#include "engine/model/linalg.h"
#include "engine/offline.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/eval/eval_compare.h"
#include "tools/eval/eval_plots.h"
#include "tools/eval/eval_report.h"
#include "tools/eval/eval_scenario_gen.h"
#include "tools/shared_flags.h"

ABSL_FLAG(std::string, data, "",
          "WOMD TFRecords or GPUDrive/Nocturne JSON files, or directories of them (the paths after it up to the next "
          "flag are data too)");
ABSL_FLAG(int, rollouts, 4, "rollouts of each scenario, 1..1024");
ABSL_FLAG(std::string, baseline, "",
          "cv: constant velocity; log: replay of the logged future (the oracle); no model needed");
// eval_: the other commands' --json is a switch.
ABSL_FLAG(std::string, eval_json, "",
          "the results as one JSON object, with per-scenario results ('-' for stdout; the table then goes to stderr)");
ABSL_FLAG(std::string, plots, "", "a directory for SVG histograms of each feature, log vs rollouts");
ABSL_FLAG(int, threads, 0, "worker threads, 1..1024; 0: the hardware's");
ABSL_FLAG(std::string, compare, "",
          "A.json (B.json follows): each metric's difference B - A of two --json results of the same scenarios and "
          "--sdc rule, with a 95 % paired bootstrap interval over scenarios");
ABSL_FLAG(std::string, ego, "",
          "the closed-loop ego benchmark: the SDC driven in the loop by log (its logged poses), slow / fast (its "
          "logged path at 0.6x / 1.3x the logged speed profile) or cruise (the Python package's cruise rule), pushed "
          "at every tick as a client pushes it; reports ego collisions by who ran into whom, off road and background "
          "collisions (docs/closed-loop.md); implies --sdc log");
ABSL_FLAG(int, bootstrap, ss::BootstrapOptions{}.resamples, "bootstrap resamples of --compare, 100..1000000");
ABSL_FLAG(std::string, submission, "",
          "score the rollouts of this submission (ours, or any model's) instead of running a policy: its scenarios "
          "must be exactly those of --data (the logs), every rollout must hold every agent valid at the current "
          "frame over the scenario's future; --sdc model only");

ABSL_FLAG(std::string, protocol, "wosac",
          "wosac: the Sim Agents metrics (the log's agents resimulated); scenario-gen: the Scenario Generation "
          "Challenge (full mode given the log's counts per type, the metric pooled over objects, the initial-state "
          "MMD beside it; --baseline log|placement)");

ABSL_FLAG(double, placement_temperature, ss::SessionOptions{}.placement_temperature,
          "--protocol scenario-gen: the temperature of a new agent's tokens (type, map segment, relative state)");
ABSL_FLAG(double, placement_top_p, ss::SessionOptions{}.placement_top_p,
          "--protocol scenario-gen: the nucleus of a new agent's tokens");
ABSL_FLAG(double, placement_clearance, ss::SessionOptions{}.placement_clearance,
          "--protocol scenario-gen: metres a new agent's box keeps from every other box when placed");
ABSL_FLAG(std::string, history, "constant-velocity",
          "--protocol scenario-gen: the generated agents' second of history: constant-velocity (back along their "
          "generated velocity) or clear (the same, held where a step back would overlap another box)");
ABSL_FLAG(double, roi_radius, ss::SessionOptions{}.roi_radius,
          "--protocol scenario-gen: metres around the SDC where agents are placed (the session's region; the "
          "placement baseline's too)");

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer eval --data FILE_OR_DIR [FILE_OR_DIR...] --json OUT.json\n"
    "                          ([--model WEIGHTS] [--mode motion|full|log|idm] | --baseline cv|log)\n"
    "                          [--sdc model|log | --ego log|slow|fast|cruise] [--rollouts K] [--seed S]\n"
    "                          [--plots DIR] [--threads N]\n"
    "                          [--top-p P] [--temperature T] [--motion-reject=false]\n"
    "                          [--wosac-submission DIR [--submission-metadata FILE.json]]\n"
    "       scenestreamer eval --data FILE_OR_DIR [FILE_OR_DIR...] --submission FILE_OR_DIR --json OUT.json\n"
    "       scenestreamer eval --compare A.json B.json [--bootstrap N] [--seed S] [--json OUT.json]\n"
    "  Rolls every scenario out K times (default 4) from its current frame to its last (any length: a 20 s scenario\n"
    "  is rolled out for 20 s) and scores the rollouts against the log: WOSAC 2025 realism (meta-metric, its ten\n"
    "  likelihoods and three buckets, collision and offroad rates, minADE), over the whole future and per window\n"
    "  (0-8 s, 8-16 s, 16 s to the end), the paper's motion metrics (ADE/FDE average and minimum over rollouts,\n"
    "  ADD/FDD diversity) and, in full mode, the initial-state MMD. Scenarios run in parallel; results do not depend\n"
    "  on the thread count (each rollout's seed comes from S, the scenario id and the rollout index).\n"
    "  --sdc model (WOSAC's rule) evaluates the SDC too; --sdc log leaves it out of the evaluated objects.\n"
    "  --mode log|idm: the rule baselines as sessions (log replay, non-reactive; IDM along the logged paths).\n"
    "  --ego P: the closed-loop ego benchmark (docs/closed-loop.md): the SDC driven by policy P in the loop, the ego's\n"
    "  collisions by who ran into whom, off road, and collisions among the others, beside the realism of the others.\n"
    "  --wosac-submission DIR: motion mode or --baseline cv, --sdc model; 32 scenarios per shard. The rollouts are\n"
    "  scored as the files hold them (float32), so scoring the files gives the same numbers. A scenario that ends at\n"
    "  its current frame (the challenge's test set) is rolled out for 80 frames and written, not scored.\n"
    "  --compare: --seed defaults to 1; --json OUT writes the comparison too.\n"
    "       scenestreamer eval --protocol scenario-gen --data ... --json OUT.json ([--model W] [--mode full] |\n"
    "                          --baseline log|placement | --submission FILE_OR_DIR) [--rollouts K] [--seed S]\n"
    "                          [--top-p P] [--temperature T] [--roi-radius R] [--placement-temperature T]\n"
    "                          [--placement-top-p P] [--placement-clearance M] [--placement-room]\n"
    "                          [--pedestrian-contact] [--history constant-velocity|clear]\n"
    "                          [--wosac-submission DIR]\n"
    "  The Scenario Generation Challenge (docs/evaluation.md): the model in full mode places the log's number of\n"
    "  vehicles, pedestrians and cyclists around the SDC (whose history is the only one given) and generates every\n"
    "  frame; scored by the challenge's metric (the sim-agents features pooled over objects, every frame) with the\n"
    "  initial-state MMD, the count check and the overlap check. --baseline log: the log (the oracle); placement:\n"
    "  the counts at random lane / sidewalk points at a log speed, constant velocity. --wosac-submission writes the\n"
    "  scenes in the challenge's format (every frame, box, type); --submission scores such files.\n";

int fail(const std::string& msg) {
  spdlog::error("eval: {}", msg);
  return 1;
}

int compare_main(const CommandLine& line) {
  const std::string other =
      line.first_given({flag(FLAGS_data), flag(FLAGS_model), flag(FLAGS_mode), flag(FLAGS_baseline), flag(FLAGS_sdc),
                        flag(FLAGS_rollouts), flag(FLAGS_plots), flag(FLAGS_threads), flag(FLAGS_top_p),
                        flag(FLAGS_temperature), flag(FLAGS_motion_reject)});
  if (!other.empty()) return fail(absl::StrCat("--compare takes two result files: ", other, " does not apply"));
  if (line.positional().size() != 1)
    return fail(absl::StrCat("--compare needs two result files (A.json B.json), got ", 1 + line.positional().size()));
  CompareRequest request{absl::GetFlag(FLAGS_compare), line.positional()[0], {}};
  request.bootstrap.resamples = absl::GetFlag(FLAGS_bootstrap);
  if (line.has(FLAGS_seed)) request.bootstrap.seed = absl::GetFlag(FLAGS_seed);
  if (request.bootstrap.resamples < 100 || request.bootstrap.resamples > 1000000)
    return fail("--bootstrap must be in 100..1000000");
  auto report = compare_eval_files(request);
  if (!report.ok()) return fail(std::string(report.status().message()));
  std::fputs(report->table.c_str(), stdout);
  if (line.has(FLAGS_eval_json)) {
    const std::string out = absl::GetFlag(FLAGS_eval_json);
    std::ofstream f(out, std::ios::binary | std::ios::trunc);
    f << json_text(report->json) << "\n";
    f.close();
    if (!f) return fail("cannot write --json " + out);
  }
  return 0;
}

int scenario_gen_main(const CommandLine& line, const std::vector<std::string>& paths) {
  ScenarioGenRun run;
  ScenarioGenOptions& o = run.options;
  const std::string other = line.first_given({flag(FLAGS_sdc), flag(FLAGS_ego), flag(FLAGS_plots)});
  if (!other.empty()) return fail("--protocol scenario-gen: " + other + " does not apply");
  if (line.has(FLAGS_mode) && absl::GetFlag(FLAGS_mode) != "full")
    return fail("--protocol scenario-gen generates the scene: --mode full only");
  const std::string model_flag = line.first_given({flag(FLAGS_model), flag(FLAGS_mode), flag(FLAGS_top_p),
                                                   flag(FLAGS_temperature), flag(FLAGS_motion_reject),
                                                   flag(FLAGS_roi_radius), flag(FLAGS_placement_temperature),
                                                   flag(FLAGS_placement_top_p), flag(FLAGS_placement_clearance),
                                                   flag(FLAGS_placement_room), flag(FLAGS_pedestrian_contact)});
  if (line.has(FLAGS_baseline)) {
    const std::string b = absl::GetFlag(FLAGS_baseline);
    if (b == "log") o.policy = ScenarioGenPolicy::log_oracle;
    else if (b == "placement") o.policy = ScenarioGenPolicy::placement;
    else return fail("--protocol scenario-gen: --baseline '" + b + "' is not log or placement");
    if (!model_flag.empty() && model_flag != "--roi-radius") return fail("--baseline runs without a model: drop " + model_flag);
  }
  if (line.has(FLAGS_submission)) {
    if (line.has(FLAGS_baseline) || !model_flag.empty() || line.has(FLAGS_rollouts) || line.has(FLAGS_seed) ||
        line.has(FLAGS_wosac_submission))
      return fail("--submission scores the scenes it holds: no policy, rollouts, seed or --wosac-submission");
    o.policy = ScenarioGenPolicy::submission;
    run.submission_in = absl::GetFlag(FLAGS_submission);
  }
  o.rollouts = absl::GetFlag(FLAGS_rollouts);
  if (o.rollouts < 1 || o.rollouts > 1024) return fail("--rollouts must be in 1..1024");
  o.session.mode = SessionMode::full;
  o.session.seed = absl::GetFlag(FLAGS_seed);
  o.session.top_p = absl::GetFlag(FLAGS_top_p);
  o.session.temperature = absl::GetFlag(FLAGS_temperature);
  o.session.motion_reject = absl::GetFlag(FLAGS_motion_reject);
  o.session.roi_radius = absl::GetFlag(FLAGS_roi_radius);
  o.session.placement_temperature = absl::GetFlag(FLAGS_placement_temperature);
  o.session.placement_top_p = absl::GetFlag(FLAGS_placement_top_p);
  o.session.placement_clearance = absl::GetFlag(FLAGS_placement_clearance);
  o.session.placement_room = absl::GetFlag(FLAGS_placement_room);
  o.session.pedestrian_contact = absl::GetFlag(FLAGS_pedestrian_contact);
  const std::string history = absl::GetFlag(FLAGS_history);
  if (history == "clear") o.history = ScenarioGenHistory::clear;
  else if (history != "constant-velocity") return fail("--history '" + history + "' is not constant-velocity or clear");
  if (line.has(FLAGS_history) && o.policy != ScenarioGenPolicy::model)
    return fail("--history shapes the model's generated agents: it needs the model policy");
  if (!(o.session.roi_radius > 0) || !std::isfinite(o.session.roi_radius)) return fail("--roi-radius must be positive");
  o.placement_radius = o.session.roi_radius;
  run.threads = absl::GetFlag(FLAGS_threads);
  if (run.threads == 0) run.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (run.threads < 1 || run.threads > 1024) return fail("--threads must be in 1..1024");
  run.json_out = absl::GetFlag(FLAGS_eval_json);
  if (line.has(FLAGS_wosac_submission)) {
    run.submission_out = absl::GetFlag(FLAGS_wosac_submission);
    o.submission_precision = true;
  }
  if (line.has(FLAGS_submission_metadata)) {
    if (!line.has(FLAGS_wosac_submission)) return fail("--submission-metadata goes with --wosac-submission");
    auto m = read_submission_metadata(absl::GetFlag(FLAGS_submission_metadata));
    if (!m.ok()) return fail(std::string(m.status().message()));
    run.metadata = std::move(*m);
  }
  enable_flush_to_zero();
  if (o.policy == ScenarioGenPolicy::model) {
    auto path = model_path();
    if (!path.ok()) return fail(std::string(path.status().message()));
    auto weights = load_weights(*path);
    if (!weights.ok()) return fail(std::string(weights.status().message()));
    auto m = Model::create(std::move(*weights));
    if (!m.ok()) return fail(absl::StrCat(*path, ": ", m.status().message()));
    run.model_path = *path;
    run.model = *m;
  }
  auto scenarios = read_scenarios(paths);
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  if (scenarios->empty()) return fail(absl::StrCat("no scenarios found in ", paths[0], paths.size() > 1 ? " ..." : ""));
  for (Scenario& s : *scenarios) run.scenarios.push_back(std::make_shared<const Scenario>(std::move(s)));
  return run_scenario_gen(run);
}

}  // namespace

int eval_main(int argc, char** argv) {
  const Command command{"scenestreamer eval", kUsage, __FILE__,
                        {flag(FLAGS_model), flag(FLAGS_mode), flag(FLAGS_seed), flag(FLAGS_sdc), flag(FLAGS_top_p),
                         flag(FLAGS_temperature), flag(FLAGS_motion_reject), flag(FLAGS_wosac_submission),
                         flag(FLAGS_submission_metadata), flag(FLAGS_kv_precision), flag(FLAGS_matmul_precision),
                         flag(FLAGS_placement_room), flag(FLAGS_pedestrian_contact)},
                        true};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  if (line.has(FLAGS_compare)) return compare_main(line);
  if (line.has(FLAGS_bootstrap)) return fail("--bootstrap goes with --compare");
  if (!line.has(FLAGS_data)) return usage_error(command, "--data is required");
  if (!line.has(FLAGS_eval_json)) return usage_error(command, "--json is required");
  // --data takes the paths after it up to the next flag (the parser leaves them positional).
  std::vector<std::string> paths = {absl::GetFlag(FLAGS_data)};
  paths.insert(paths.end(), line.positional().begin(), line.positional().end());
  const std::string protocol = absl::GetFlag(FLAGS_protocol);
  if (protocol == "scenario-gen") return scenario_gen_main(line, paths);
  if (protocol != "wosac") return fail("--protocol '" + protocol + "' is not wosac or scenario-gen");
  if (const std::string g = line.first_given({flag(FLAGS_placement_temperature), flag(FLAGS_placement_top_p),
                                              flag(FLAGS_placement_clearance), flag(FLAGS_placement_room),
                                              flag(FLAGS_pedestrian_contact), flag(FLAGS_history)});
      !g.empty())
    return fail(g + " goes with --protocol scenario-gen");

  EvalOptions options;
  EvalRunInfo run;
  if (line.has(FLAGS_baseline)) {
    const std::string b = absl::GetFlag(FLAGS_baseline);
    if (b == "cv") options.policy = EvalPolicy::constant_velocity;
    else if (b == "log") options.policy = EvalPolicy::log_replay;
    else return fail("--baseline '" + b + "' is not cv or log");
    const std::string model_flag =
        line.first_given({flag(FLAGS_model), flag(FLAGS_mode), flag(FLAGS_top_p), flag(FLAGS_temperature),
                          flag(FLAGS_motion_reject)});
    if (!model_flag.empty()) return fail("--baseline runs without a model: drop " + model_flag);
  }
  const std::string sdc = absl::GetFlag(FLAGS_sdc), mode = absl::GetFlag(FLAGS_mode);
  if (line.has(FLAGS_submission)) {
    const std::string other = line.first_given(
        {flag(FLAGS_baseline), flag(FLAGS_model), flag(FLAGS_mode), flag(FLAGS_rollouts), flag(FLAGS_seed),
         flag(FLAGS_wosac_submission), flag(FLAGS_submission_metadata), flag(FLAGS_top_p), flag(FLAGS_temperature),
         flag(FLAGS_motion_reject)});
    if (!other.empty()) return fail("--submission scores the rollouts it holds: " + other + " does not apply");
    if (sdc != "model")
      return fail("--submission: a submission's rollouts drive every agent, the SDC included (--sdc model only)");
    options.policy = EvalPolicy::submission;
  }
  const bool write_submission = line.has(FLAGS_wosac_submission);
  const std::string submission_dir = absl::GetFlag(FLAGS_wosac_submission);
  if (line.has(FLAGS_submission_metadata) && !write_submission)
    return fail("--submission-metadata goes with --wosac-submission");
  if (write_submission) {
    if (options.policy == EvalPolicy::log_replay)
      return fail("--wosac-submission: log replay leaves agents without a state where the log has none; a "
                  "submission holds every agent at every frame (use the model or --baseline cv)");
    if (mode != "motion")
      return fail("--wosac-submission takes motion mode: the challenge resimulates the log's agents, and full mode's "
                  "generated agents have no place in a submission");
    if (sdc != "model")
      return fail("--wosac-submission: the challenge's rule is that the simulation drives every agent, the SDC "
                  "included (--sdc model)");
    options.submission_precision = true;
  }
  if (sdc == "model") options.sdc = SdcRule::model;
  else if (sdc == "log") options.sdc = SdcRule::log;
  else return fail("--sdc '" + sdc + "' is not model or log");
  if (auto m = session_mode_from_name(mode); m && *m != SessionMode::densify) options.session.mode = *m;
  else return fail("--mode '" + mode + "' is not motion, full, log or idm");
  if (line.has(FLAGS_ego)) {
    const std::string e = absl::GetFlag(FLAGS_ego);
    options.ego = ego_policy_from_name(e);
    if (!options.ego) return fail("--ego '" + e + "' is not log, slow, fast or cruise");
    if (options.policy != EvalPolicy::model)
      return fail("--ego drives the SDC through a session: the model or a rule mode (--mode log|idm), not --baseline or --submission");
    if (line.has(FLAGS_sdc) && sdc != "log") return fail("--ego drives the SDC itself: --sdc " + sdc + " does not apply");
    if (write_submission) return fail("--ego: a WOSAC submission drives the SDC by the policy (--sdc model)");
    options.sdc = SdcRule::log;
  } else if (options.session.mode == SessionMode::log || options.session.mode == SessionMode::idm) {
    if (write_submission) return fail("--wosac-submission: --mode " + mode + " is a baseline that reads the logged future");
  }
  options.rollouts = absl::GetFlag(FLAGS_rollouts);
  options.session.seed = absl::GetFlag(FLAGS_seed);
  options.session.top_p = absl::GetFlag(FLAGS_top_p);
  options.session.temperature = absl::GetFlag(FLAGS_temperature);
  options.session.motion_reject = absl::GetFlag(FLAGS_motion_reject);
  int threads = absl::GetFlag(FLAGS_threads);
  if (threads == 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (!(options.session.top_p > 0 && options.session.top_p <= 1)) return fail("--top-p must be in (0, 1]");
  if (!(options.session.temperature > 0) || !std::isfinite(options.session.temperature))
    return fail("--temperature must be positive");
  if (options.rollouts < 1 || options.rollouts > 1024) return fail("--rollouts must be in 1..1024");
  if (threads < 1 || threads > 1024) return fail("--threads must be in 1..1024");

  enable_flush_to_zero();
  std::shared_ptr<const Model> model;
  if (options.policy == EvalPolicy::model) {
    auto model_opts = model_options();
    if (!model_opts.ok()) return fail(std::string(model_opts.status().message()));
    auto m = model_load(*model_opts);
    if (!m.ok()) return fail(std::string(m.status().message()));
    run.model_path = model_opts->model_path;
    model = *m;
  }
  SubmissionMetadata metadata;
  if (line.has(FLAGS_submission_metadata)) {
    auto m = read_submission_metadata(absl::GetFlag(FLAGS_submission_metadata));
    if (!m.ok()) return fail(std::string(m.status().message()));
    metadata = std::move(*m);
  }
  auto scenarios = read_scenarios(paths);
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  if (scenarios->empty()) return fail(absl::StrCat("no scenarios found in ", paths[0], paths.size() > 1 ? " ..." : ""));
  std::vector<std::shared_ptr<const Scenario>> all;
  int history_only = 0;  // scenarios that end at their current frame (the challenge's test set)
  std::vector<std::string> no_ego;  // --ego: scenarios with no SDC valid at the current frame, left out
  for (Scenario& s : *scenarios) {
    if (options.ego && (s.sdc_track_index < 0 || !s.tracks[s.sdc_track_index].states[s.current_time_index].valid)) {
      no_ego.push_back(s.id);
      continue;
    }
    if (write_submission && s.num_frames() == s.current_time_index + 1) {
      s = with_empty_future(s, kChallengeFutureFrames);
      ++history_only;
    }
    all.push_back(std::make_shared<const Scenario>(std::move(s)));
  }
  scenarios->clear();
  if (!no_ego.empty())
    spdlog::warn("eval: --ego: {} scenario(s) name no SDC valid at the current frame and are left out (e.g. {})",
                 no_ego.size(), no_ego[0]);
  if (all.empty()) return fail("--ego: no scenario names an SDC to drive");

  // --submission: each log's rollouts, matched by scenario id in both directions.
  std::vector<const ScenarioRollouts*> submitted(all.size(), nullptr);
  Submission submission;
  if (options.policy == EvalPolicy::submission) {
    auto read = read_submission({absl::GetFlag(FLAGS_submission)});
    if (!read.ok()) return fail(std::string(read.status().message()));
    submission = std::move(*read);
    std::map<std::string, const ScenarioRollouts*> by_id;
    for (const ScenarioRollouts& r : submission.rollouts) by_id[r.scenario_id] = &r;
    for (size_t i = 0; i < all.size(); ++i) {
      auto it = by_id.find(all[i]->id);
      if (it == by_id.end())
        return fail(absl::StrCat("--submission has no rollouts of scenario ", all[i]->id, " (in --data)"));
      submitted[i] = it->second;
      by_id.erase(it);
    }
    if (!by_id.empty())
      return fail(absl::StrCat("--submission has ", by_id.size(), " scenario(s) that --data does not, e.g. ",
                               by_id.begin()->first, ": give their logs too"));
    options.rollouts = static_cast<int>(submitted[0]->joint_scenes.size());
    for (size_t i = 0; i < all.size(); ++i)
      if (static_cast<int>(submitted[i]->joint_scenes.size()) != options.rollouts)
        return fail(absl::StrCat("--submission: scenario ", all[i]->id, " has ", submitted[i]->joint_scenes.size(),
                                 " rollouts, ", all[0]->id, " has ", options.rollouts,
                                 "; the metrics compare scenarios with the same number"));
  }
  // --wosac-submission: each scenario's rollouts, written shard by shard as soon as a shard's scenarios are done.
  const int shards = submission_shard_count(static_cast<int>(all.size()));
  std::vector<std::optional<ScenarioRollouts>> to_write(all.size());
  std::vector<int> shard_left(shards, 0);
  for (size_t i = 0; i < all.size(); ++i) ++shard_left[i / kScenariosPerShard];
  std::vector<ScenarioRollouts> written;  // kept for challenge_problems: trajectories dropped once written
  if (write_submission) {
    std::error_code ec;
    std::filesystem::create_directories(submission_dir, ec);
    if (ec) return fail(absl::StrCat("cannot create --wosac-submission ", submission_dir, ": ", ec.message()));
  }

  // A bounded pool: each worker takes the next scenario; results land in the scenario's slot, so their order (and,
  // with per-rollout seeds, their values) does not depend on which thread ran what.
  std::unique_ptr<MapCache> maps = model ? std::make_unique<MapCache>(model) : nullptr;
  std::vector<std::optional<absl::StatusOr<ScenarioEvaluation>>> results(all.size());
  std::atomic<size_t> next{0};
  std::mutex log_mu;
  const auto start = std::chrono::steady_clock::now();
  std::optional<absl::Status> write_error;
  auto worker = [&] {
    for (size_t i = next++; i < all.size(); i = next++) {
      std::vector<JointScene> scenes;
      if (submitted[i]) {
        auto given = scenes_from_rollouts(*all[i], *submitted[i], absl::GetFlag(FLAGS_submission));
        if (!given.ok()) {
          results[i] = given.status();
        } else {
          results[i] = evaluate_scenario(all[i], options, model, maps.get(), &*given);
        }
      } else {
        results[i] = evaluate_scenario(all[i], options, model, maps.get(), nullptr, write_submission ? &scenes : nullptr);
      }
      std::optional<ScenarioRollouts> rollouts;
      if (write_submission && results[i]->ok()) {
        auto r = rollouts_from_scenes(*all[i], scenes);
        if (!r.ok()) results[i] = r.status();
        else rollouts = std::move(*r);
      }
      const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::lock_guard<std::mutex> lock(log_mu);
      spdlog::info("eval: {} {} ({:.0f} s)", all[i]->id, results[i]->ok() ? "done" : "failed", secs);
      if (!rollouts) continue;
      to_write[i] = std::move(rollouts);
      const int shard = static_cast<int>(i / kScenariosPerShard);
      if (--shard_left[shard] > 0 || write_error) continue;
      std::vector<ScenarioRollouts> batch;
      for (size_t k = shard * size_t{kScenariosPerShard}; k < std::min(all.size(), (shard + 1) * size_t{kScenariosPerShard}); ++k) {
        batch.push_back(std::move(*to_write[k]));
        to_write[k].reset();
      }
      const std::string path = submission_shard_path(submission_dir, shard, shards);
      if (auto st = write_submission_shard(path, batch, metadata); !st.ok()) write_error = st;
      for (ScenarioRollouts& r : batch)
        written.push_back({r.scenario_id, std::vector<std::vector<SimulatedTrajectory>>(r.joint_scenes.size())});
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::min<int>(threads, static_cast<int>(all.size())); ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();
  std::vector<ScenarioEvaluation> evaluations;
  for (auto& r : results) {
    if (!r->ok()) return fail(std::string(r->status().message()));
    evaluations.push_back(std::move(**r));
  }
  if (write_error) return fail(std::string(write_error->message()));

  const DatasetEvaluation d = aggregate(evaluations);
  run.policy = options.policy;
  run.sdc = options.sdc;
  run.mode = options.session.mode;
  run.rollouts = options.rollouts;
  run.seed = options.session.seed;
  run.top_p = options.session.top_p, run.temperature = options.session.temperature;
  run.motion_reject = options.session.motion_reject;
  run.ego = options.ego;
  run.no_ego = static_cast<int>(no_ego.size());
  const std::string json = json_text(eval_json(run, d, evaluations)) + "\n";
  const std::string out = absl::GetFlag(FLAGS_eval_json);
  if (out == "-") {
    std::fputs(json.c_str(), stdout);
  } else {
    std::ofstream f(out, std::ios::binary | std::ios::trunc);
    f << json;
    f.close();
    if (!f) return fail("cannot write --json " + out);
  }
  std::fputs(eval_table(run, d).c_str(), out == "-" ? stderr : stdout);
  if (write_submission) {
    std::FILE* text = out == "-" ? stderr : stdout;
    std::fprintf(text, "\nsubmission: %zu scenarios x %d rollouts in %d shard(s) in %s\n", written.size(),
                 options.rollouts, shards, submission_dir.c_str());
    if (history_only)
      std::fprintf(text, "  %d scenario(s) end at their current frame (the challenge's test set): rolled out for %d "
                   "frames and written, not scored (no logged future)\n", history_only, kChallengeFutureFrames);
    std::vector<const Scenario*> logs;
    for (const auto& s : all) logs.push_back(s.get());
    for (const std::string& p : challenge_problems(written, logs, metadata))
      std::fprintf(text, "  not yet valid for the challenge: %s\n", p.c_str());
  }
  if (const std::string plots = absl::GetFlag(FLAGS_plots); !plots.empty()) {
    std::vector<std::string> written;
    const std::string label = options.policy == EvalPolicy::model ? absl::StrCat("model, ", mode, " mode")
                                                                  : std::string(eval_policy_name(options.policy));
    if (auto st = write_feature_plots(plots, label, d, &written); !st.ok())
      return fail(std::string(st.message()));
    std::fprintf(out == "-" ? stderr : stdout, "\nplots: %zu SVG files in %s\n", written.size(), plots.c_str());
  }
  return 0;
}

}  // namespace ss::cli
