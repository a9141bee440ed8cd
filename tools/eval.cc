// scenestreamer eval --data FILE_OR_DIR... --model W --mode motion|full --rollouts K --seed S [--baseline cv|log]
//                   [--sdc model|log] --json OUT [--plots DIR] [--threads N]
// scenestreamer eval --compare A.json B.json [--bootstrap N] [--seed S] [--json OUT]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <thread>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "engine/eval/aggregate.h"
#include "engine/eval/evaluate.h"
#include "engine/model/linalg.h"
#include "engine/model/weights.h"
#include "engine/scenario/read.h"
#include "tools/cli_args.h"
#include "tools/commands.h"
#include "tools/eval/eval_compare.h"
#include "tools/eval/eval_plots.h"
#include "tools/eval/eval_report.h"

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer eval --data FILE_OR_DIR [FILE_OR_DIR...] --json OUT.json\n"
    "                          ([--model WEIGHTS] [--mode motion|full] | --baseline cv|log)\n"
    "                          [--sdc model|log] [--rollouts K] [--seed S] [--plots DIR] [--threads N]\n"
    "       scenestreamer eval --compare A.json B.json [--bootstrap N] [--seed S] [--json OUT.json]\n"
    "  Rolls every scenario out K times (default 4) from its current frame to its last (any length: a 20 s scenario\n"
    "  is rolled out for 20 s) and scores the rollouts against the log: WOSAC 2025 realism (meta-metric, its ten\n"
    "  likelihoods and three buckets, collision and offroad rates, minADE), over the whole future and per window\n"
    "  (0-8 s, 8-16 s, 16 s to the end), the paper's motion metrics (ADE/FDE average and minimum over rollouts,\n"
    "  ADD/FDD diversity) and, in full mode, the initial-state MMD. Scenarios run in parallel; results do not depend\n"
    "  on the thread count (each rollout's seed comes from S, the scenario id and the rollout index).\n"
    "  --data        WOMD TFRecords or GPUDrive/Nocturne JSON files, or directories of them\n"
    "  --baseline    cv: constant velocity; log: replay of the logged future (the oracle); no model needed\n"
    "  --sdc         model (default): the policy drives the SDC like every other agent and the SDC is evaluated\n"
    "                (WOSAC's rule); log: the SDC follows its log, as an RL client's ego would, and is left out of\n"
    "                the evaluated objects\n"
    "  --json        the results as one JSON object, with per-scenario results ('-' for stdout; the table then goes\n"
    "                to stderr)\n"
    "  --plots DIR   SVG histograms of each feature, log vs rollouts\n"
    "  --threads N   worker threads (default: the hardware's)\n"
    "  --compare     two --json results of the same scenarios and --sdc rule: each metric's difference B - A with a\n"
    "                95 % paired bootstrap interval over scenarios (--bootstrap N resamples, default 10000; --seed S,\n"
    "                default 1); --json OUT writes the comparison too\n";

int fail(const std::string& msg) {
  std::fprintf(stderr, "eval: %s\n", msg.c_str());
  return 1;
}

template <typename T>
bool parse_number(const Args& args, const char* flag, T* out) {
  if (!args.has(flag)) return true;
  if (absl::SimpleAtoi(args.get(flag), out)) return true;
  std::fprintf(stderr, "eval: --%s '%s' is not a whole number\n", flag, args.get(flag).c_str());
  return false;
}

int compare_main(const Args& args) {
  for (const char* flag : {"data", "model", "mode", "baseline", "sdc", "rollouts", "plots", "threads"})
    if (args.has(flag)) return fail(absl::StrCat("--compare takes two result files: --", flag, " does not apply"));
  if (args.positional.size() != 1)
    return fail(absl::StrCat("--compare needs two result files (A.json B.json), got ", 1 + args.positional.size()));
  CompareRequest request{args.get("compare"), args.positional[0], {}};
  if (!parse_number(args, "bootstrap", &request.bootstrap.resamples) ||
      !parse_number(args, "seed", &request.bootstrap.seed))
    return 2;
  if (request.bootstrap.resamples < 100 || request.bootstrap.resamples > 1000000)
    return fail("--bootstrap must be in 100..1000000");
  auto report = compare_eval_files(request);
  if (!report.ok()) return fail(std::string(report.status().message()));
  std::fputs(report->table.c_str(), stdout);
  if (args.has("json")) {
    const std::string out = args.get("json");
    std::ofstream f(out, std::ios::binary | std::ios::trunc);
    f << report->json.dump(2) << "\n";
    f.close();
    if (!f) return fail("cannot write --json " + out);
  }
  return 0;
}

}  // namespace

int eval_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1,
                         {"data", "model", "mode", "rollouts", "seed", "baseline", "sdc", "json", "plots", "threads",
                          "compare", "bootstrap"},
                         {"help"});
  if (args.ok() && !args->has("help") && args->has("compare")) return compare_main(*args);
  if (args.ok() && args->has("bootstrap") && !args->has("help")) return fail("--bootstrap goes with --compare");
  if (!args.ok() || args->has("help") || !args->has("data") || !args->has("json")) {
    if (!args.ok()) std::fprintf(stderr, "eval: %s\n", std::string(args.status().message()).c_str());
    else if (!args->has("help")) std::fprintf(stderr, "eval: --%s is required\n", args->has("data") ? "json" : "data");
    std::fputs(kUsage, args.ok() && args->has("help") ? stdout : stderr);
    return args.ok() && args->has("help") ? 0 : 2;
  }
  // --data takes the paths after it up to the next flag (the parser leaves them positional).
  std::vector<std::string> paths = {args->get("data")};
  paths.insert(paths.end(), args->positional.begin(), args->positional.end());

  EvalOptions options;
  EvalRunInfo run;
  if (args->has("baseline")) {
    const std::string b = args->get("baseline");
    if (b == "cv") options.policy = EvalPolicy::constant_velocity;
    else if (b == "log") options.policy = EvalPolicy::log_replay;
    else return fail("--baseline '" + b + "' is not cv or log");
    if (args->has("model") || args->has("mode")) return fail("--baseline runs without a model: drop --model and --mode");
  }
  const std::string sdc = args->get("sdc", "model");
  if (sdc == "model") options.sdc = SdcRule::model;
  else if (sdc == "log") options.sdc = SdcRule::log;
  else return fail("--sdc '" + sdc + "' is not model or log");
  const std::string mode = args->get("mode", "motion");
  if (mode == "motion") options.session.mode = SessionMode::motion;
  else if (mode == "full") options.session.mode = SessionMode::full;
  else return fail("--mode '" + mode + "' is not motion or full");
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (!parse_number(*args, "rollouts", &options.rollouts) || !parse_number(*args, "seed", &options.session.seed) ||
      !parse_number(*args, "threads", &threads))
    return 2;
  if (options.rollouts < 1 || options.rollouts > 1024) return fail("--rollouts must be in 1..1024");
  if (threads < 1 || threads > 1024) return fail("--threads must be in 1..1024");

  enable_flush_to_zero();
  std::shared_ptr<const Model> model;
  if (options.policy == EvalPolicy::model) {
    auto path = model_path(*args);
    if (!path.ok()) return fail(std::string(path.status().message()));
    auto weights = load_weights(*path);
    if (!weights.ok()) return fail(std::string(weights.status().message()));
    auto m = Model::create(std::move(*weights));
    if (!m.ok()) return fail(absl::StrCat(*path, ": ", m.status().message()));
    run.model_path = *path;
    model = *m;
  }
  auto scenarios = read_scenarios(paths);
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  if (scenarios->empty()) return fail(absl::StrCat("no scenarios found in ", paths[0], paths.size() > 1 ? " ..." : ""));
  std::vector<std::shared_ptr<const Scenario>> all;
  for (Scenario& s : *scenarios) all.push_back(std::make_shared<const Scenario>(std::move(s)));
  scenarios->clear();

  // A bounded pool: each worker takes the next scenario; results land in the scenario's slot, so their order (and,
  // with per-rollout seeds, their values) does not depend on which thread ran what.
  std::unique_ptr<MapCache> maps = model ? std::make_unique<MapCache>(model) : nullptr;
  std::vector<std::optional<absl::StatusOr<ScenarioEvaluation>>> results(all.size());
  std::atomic<size_t> next{0};
  std::mutex log_mu;
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&] {
    for (size_t i = next++; i < all.size(); i = next++) {
      results[i] = evaluate_scenario(all[i], options, model, maps.get());
      const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::lock_guard<std::mutex> lock(log_mu);
      std::fprintf(stderr, "eval: %s %s (%.0f s)\n", all[i]->id.c_str(), results[i]->ok() ? "done" : "failed", secs);
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

  const DatasetEvaluation d = aggregate(evaluations);
  run.policy = options.policy;
  run.sdc = options.sdc;
  run.mode = options.session.mode;
  run.rollouts = options.rollouts;
  run.seed = options.session.seed;
  const std::string json = eval_json(run, d, evaluations).dump(2) + "\n";
  const std::string out = args->get("json");
  if (out == "-") {
    std::fputs(json.c_str(), stdout);
  } else {
    std::ofstream f(out, std::ios::binary | std::ios::trunc);
    f << json;
    f.close();
    if (!f) return fail("cannot write --json " + out);
  }
  std::fputs(eval_table(run, d).c_str(), out == "-" ? stderr : stdout);
  if (args->has("plots")) {
    std::vector<std::string> written;
    const std::string label = options.policy == EvalPolicy::model ? absl::StrCat("model, ", mode, " mode")
                                                                  : std::string(eval_policy_name(options.policy));
    if (auto st = write_feature_plots(args->get("plots"), label, d, &written); !st.ok())
      return fail(std::string(st.message()));
    std::fprintf(out == "-" ? stderr : stdout, "\nplots: %zu SVG files in %s\n", written.size(),
                 args->get("plots").c_str());
  }
  return 0;
}

}  // namespace ss::cli
