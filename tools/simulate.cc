// scenestreamer simulate --scenario FILE --model W --mode motion|full|densify --sdc model|log --steps N --seed S
//                        [--rollout K] --out FILE
#include <cstdio>

#include "absl/strings/numbers.h"
#include "engine/eval/evaluate.h"
#include "engine/eval/model_rollout.h"
#include "engine/model/linalg.h"
#include "engine/model/weights.h"
#include "engine/scenario/read.h"
#include "engine/sim/map_cache.h"
#include "engine/sim/rollout_export.h"
#include "engine/sim/session.h"
#include "tools/cli_args.h"
#include "tools/commands.h"

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer simulate --scenario FILE [--model WEIGHTS] --out OUT.tfrecord\n"
    "                              [--mode motion|full|densify] [--sdc model|log] [--steps N] [--seed S] [--rollout K]\n"
    "                              [--index I]\n"
    "                              [--top-p P] [--temperature T] [--max-agents N] [--densify-target N]\n"
    "  Rolls the scenario out from its current step for N model steps (0.5 s each; default: to the scenario's last\n"
    "  frame, 16 steps for a 91-frame WOMD scenario, 38 for a 20 s one; more steps go on past the log) and writes it\n"
    "  as a complete 10 Hz WOMD Scenario: the log's frames up to its current frame as logged (same id, current index,\n"
    "  SDC, tracks to predict), the rollout after it; z held from each agent's last logged z; agents the model\n"
    "  created as new tracks with ids above the log's.\n"
    "  --sdc model (default): the model drives the SDC like every other agent; no logged pose after the current\n"
    "        frame reaches the session. log: the SDC replays its logged poses while the log lasts (then keeps its last\n"
    "        control), as an RL client's ego would.\n"
    "  --seed S --rollout K (default 0): the session's seed is the one `eval --seed S` gives the scenario's K-th\n"
    "        rollout, so simulate reproduces eval's rollouts one by one (and `convert --wosac-submission` turns them\n"
    "        into the submission `eval --wosac-submission` writes).\n";

int fail(const std::string& msg) {
  std::fprintf(stderr, "simulate: %s\n", msg.c_str());
  return 1;
}

}  // namespace

int simulate_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1,
                         {"scenario", "model", "mode", "sdc", "steps", "seed", "out", "index", "top-p", "temperature",
                          "max-agents", "densify-target", "rollout"},
                         {"help"});
  if (!args.ok() || args->has("help") || !args->positional.empty() || !args->has("scenario") ||
      !args->has("out")) {
    if (!args.ok()) std::fprintf(stderr, "simulate: %s\n", std::string(args.status().message()).c_str());
    else if (!args->positional.empty()) std::fprintf(stderr, "simulate: unexpected argument '%s'\n", args->positional[0].c_str());
    std::fputs(kUsage, args.ok() && args->has("help") ? stdout : stderr);
    return args.ok() && args->has("help") ? 0 : 2;
  }
  SessionOptions o;
  const std::string mode = args->get("mode", "motion");
  if (mode == "motion") o.mode = SessionMode::motion;
  else if (mode == "full") o.mode = SessionMode::full;
  else if (mode == "densify") o.mode = SessionMode::densify;
  else return fail("--mode '" + mode + "' is not motion, full or densify");
  const std::string sdc = args->get("sdc", "model");
  SdcRule sdc_rule = SdcRule::model;
  if (sdc == "log") sdc_rule = SdcRule::log;
  else if (sdc != "model") return fail("--sdc '" + sdc + "' is not model or log");
  int steps = -1, index = 0, rollout = 0;
  auto number = [&](const char* flag, auto* out) {
    if (!args->has(flag)) return true;
    using T = std::remove_pointer_t<decltype(out)>;
    bool ok;
    if constexpr (std::is_floating_point_v<T>) ok = absl::SimpleAtod(args->get(flag), out);
    else ok = absl::SimpleAtoi(args->get(flag), out);
    if (!ok) std::fprintf(stderr, "simulate: --%s '%s' is not a number\n", flag, args->get(flag).c_str());
    return ok;
  };
  if (!number("steps", &steps) || !number("seed", &o.seed) || !number("index", &index) ||
      !number("rollout", &rollout) || !number("top-p", &o.top_p) ||
      !number("temperature", &o.temperature) || !number("max-agents", &o.max_agents) ||
      !number("densify-target", &o.densify_target))
    return 2;
  if (args->has("steps") && (steps < 0 || steps > 100000)) return fail("--steps must be in 0..100000");
  if (rollout < 0 || rollout > 1000000) return fail("--rollout must be in 0..1000000");

  enable_flush_to_zero();
  auto path = model_path(*args);
  if (!path.ok()) return fail(std::string(path.status().message()));
  auto weights = load_weights(*path);
  if (!weights.ok()) return fail(std::string(weights.status().message()));
  auto model = Model::create(std::move(*weights));
  if (!model.ok()) return fail(std::string(model.status().message()));
  auto scenarios = read_scenarios(args->get("scenario"));
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  if (index < 0 || index >= static_cast<int>(scenarios->size()))
    return fail("--index " + std::to_string(index) + " is outside the file's " + std::to_string(scenarios->size()) +
                " scenarios");
  auto scenario = std::make_shared<const Scenario>((*scenarios)[index]);
  MapCache maps(*model);
  auto map = maps.get(*scenario);
  if (!map.ok()) return fail(std::string(map.status().message()));
  const uint64_t seed = o.seed;
  o.seed = rollout_seed(seed, scenario->id, rollout);
  auto results = run_model_rollout(*model, scenario, *map, o, sdc_rule, steps);
  if (!results.ok()) return fail(std::string(results.status().message()));
  auto out = rollout_to_scenario(*scenario, *results);
  if (!out.ok()) return fail(std::string(out.status().message()));
  if (auto st = write_scenarios_tfrecord(args->get("out"), {*out}); !st.ok()) return fail(std::string(st.message()));
  std::printf("simulated %s (%s mode, --sdc %s, seed %llu, rollout %d): %zu steps, %zu agents at the end, %zu tracks "
              "in all -> %s\n",
              scenario->id.c_str(), mode.c_str(), sdc.c_str(), static_cast<unsigned long long>(seed), rollout,
              results->size() - 1, results->back().agents.size(), out->tracks.size(), args->get("out").c_str());
  return 0;
}

}  // namespace ss::cli
