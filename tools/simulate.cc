// scenestreamer simulate --scenario FILE --model W --mode motion|full|densify|log|idm --sdc model|log --steps N --seed S
//                        [--rollout K] --out FILE
#include <cstdio>

#include "absl/flags/flag.h"
#include "offline/eval/evaluate.h"
#include "offline/eval/model_rollout.h"
#include "offline/eval/scenario_gen.h"
#include "engine/model/linalg.h"
#include "engine/offline.h"
#include "engine/sim/rollout_export.h"
#include "spdlog/spdlog.h"
#include "common/command_line.h"
#include "tools/commands.h"
#include "tools/shared_flags.h"

// simulate_: bench's --scenario and --steps have other defaults, render's --scenario another meaning.
ABSL_FLAG(std::string, simulate_scenario, "", "the scenario file: WOMD TFRecord or GPUDrive/Nocturne JSON (required)");
ABSL_FLAG(int, simulate_steps, -1, "model steps to roll out, 0..100000; -1: to the scenario's last frame");
ABSL_FLAG(int, rollout, 0,
          "K: with --seed S, the session's seed is the one `eval --seed S` gives the scenario's K-th rollout");
ABSL_FLAG(int, max_agents, ss::SessionOptions{}.max_agents, "the cap on agents alive at once");
ABSL_FLAG(int, densify_target, ss::SessionOptions{}.densify_target, "densify mode: agents to reach at the first step");
ABSL_FLAG(std::string, agent_counts, "",
          "full mode: the agents to place, V,P,C (vehicles, pedestrians, cyclists), or 'log' for the scenario's own "
          "(every agent valid at its current frame but the SDC); the SDC is taken from the log");

namespace ss::cli {
namespace {

constexpr const char* kUsage =
    "usage: scenestreamer simulate --scenario FILE [--model WEIGHTS] --out OUT.tfrecord\n"
    "                              [--mode motion|full|densify|log|idm] [--sdc model|log] [--steps N] [--seed S] [--rollout K]\n"
    "                              [--index I]\n"
    "                              [--top-p P] [--temperature T] [--motion-reject=false] [--max-agents N] [--densify-target N]\n"
    "                              [--agent-counts V,P,C|log]\n"
    "  Rolls the scenario out from its current step for N model steps (0.5 s each; default: to the scenario's last\n"
    "  frame, 16 steps for a 91-frame WOMD scenario, 38 for a 20 s one; more steps go on past the log) and writes it\n"
    "  as a complete 10 Hz WOMD Scenario: the log's frames up to its current frame as logged (same id, current index,\n"
    "  SDC, tracks to predict), the rollout after it; z held from each agent's last logged z; agents the model\n"
    "  created as new tracks with ids above the log's.\n"
    "  --sdc model (default): the model drives the SDC like every other agent; no logged pose after the current\n"
    "        frame reaches the session. log: the SDC replays its logged poses while the log lasts (then keeps its last\n"
    "        control), as an RL client's ego would.\n"
    "  --seed S --rollout K: the session's seed is the one `eval --seed S` gives the scenario's K-th rollout, so\n"
    "        simulate reproduces eval's rollouts one by one (and `convert --wosac-submission` turns them into the\n"
    "        submission `eval --wosac-submission` writes).\n"
    "  --mode log|idm: the rule baselines; they read the scenario's logged future (the model modes never do).\n"
    "  --agent-counts (full mode): exactly V vehicles, P pedestrians and C cyclists placed at the first step around\n"
    "        the SDC, which is taken from the log (the Scenario Generation Challenge's input); none joins or retires\n"
    "        later. log: the scenario's own counts.\n";

int fail(const std::string& msg) {
  spdlog::error("simulate: {}", msg);
  return 1;
}

}  // namespace

int simulate_main(int argc, char** argv) {
  const Command command{"scenestreamer simulate", kUsage, __FILE__,
                        {flag(FLAGS_model), flag(FLAGS_out), flag(FLAGS_mode), flag(FLAGS_sdc), flag(FLAGS_seed),
                         flag(FLAGS_index), flag(FLAGS_top_p), flag(FLAGS_temperature), flag(FLAGS_motion_reject),
                         flag(FLAGS_placement_room), flag(FLAGS_pedestrian_contact), flag(FLAGS_kv_precision),
                         flag(FLAGS_matmul_precision)}};
  CommandLine line;
  if (auto exit_code = parse_command(command, argc, argv, &line)) return *exit_code;
  if (!line.has(FLAGS_simulate_scenario) || !line.has(FLAGS_out))
    return usage_error(command, "--scenario and --out are required");
  SessionOptions o;
  const std::string mode = absl::GetFlag(FLAGS_mode);
  if (auto m = session_mode_from_name(mode)) o.mode = *m;
  else return fail("--mode '" + mode + "' is not motion, full, densify, log or idm");
  const std::string sdc = absl::GetFlag(FLAGS_sdc);
  SdcRule sdc_rule = SdcRule::model;
  if (sdc == "log") sdc_rule = SdcRule::log;
  else if (sdc != "model") return fail("--sdc '" + sdc + "' is not model or log");
  o.seed = absl::GetFlag(FLAGS_seed);
  o.top_p = absl::GetFlag(FLAGS_top_p);
  o.temperature = absl::GetFlag(FLAGS_temperature);
  o.motion_reject = absl::GetFlag(FLAGS_motion_reject);
  o.placement_room = absl::GetFlag(FLAGS_placement_room);
  o.pedestrian_contact = absl::GetFlag(FLAGS_pedestrian_contact);
  if (o.placement_room && o.mode != SessionMode::full && o.mode != SessionMode::densify)
    return fail("--placement-room shapes where new agents are placed: --mode full or densify");
  if (o.pedestrian_contact && (o.mode == SessionMode::log || o.mode == SessionMode::idm))
    return fail("--pedestrian-contact shapes the model's motion: not with --mode " + mode);
  o.max_agents = absl::GetFlag(FLAGS_max_agents);
  o.densify_target = absl::GetFlag(FLAGS_densify_target);
  const int steps = absl::GetFlag(FLAGS_simulate_steps), index = absl::GetFlag(FLAGS_index),
            rollout = absl::GetFlag(FLAGS_rollout);
  if (steps < -1 || steps > 100000) return fail("--steps must be in 0..100000 (or -1: to the last frame)");
  if (rollout < 0 || rollout > 1000000) return fail("--rollout must be in 0..1000000");

  enable_flush_to_zero();
  auto model_opts = model_options();
  if (!model_opts.ok()) return fail(std::string(model_opts.status().message()));
  auto model = model_load(*model_opts);
  if (!model.ok()) return fail(std::string(model.status().message()));
  auto scenarios = read_scenarios(absl::GetFlag(FLAGS_simulate_scenario));
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  if (index < 0 || index >= static_cast<int>(scenarios->size()))
    return fail("--index " + std::to_string(index) + " is outside the file's " + std::to_string(scenarios->size()) +
                " scenarios");
  auto scenario = std::make_shared<const Scenario>((*scenarios)[index]);
  if (line.has(FLAGS_agent_counts)) {
    const std::string counts = absl::GetFlag(FLAGS_agent_counts);
    if (o.mode != SessionMode::full) return fail("--agent-counts goes with --mode full");
    if (counts == "log") {
      const std::array<int, 3> c = scenario_gen_counts(*scenario);
      o.agent_counts.assign(c.begin(), c.end());
    } else {
      auto c = parse_agent_counts(counts);
      if (!c.ok()) return fail("--agent-counts: " + std::string(c.status().message()));
      o.agent_counts.assign(c->begin(), c->end());
    }
  }
  MapCache maps(*model);
  auto map = maps.get(*scenario);
  if (!map.ok()) return fail(std::string(map.status().message()));
  const uint64_t seed = o.seed;
  o.seed = rollout_seed(seed, scenario->id, rollout);
  auto results = run_model_rollout(*model, scenario, *map, o, sdc_rule, steps);
  if (!results.ok()) return fail(std::string(results.status().message()));
  auto out = rollout_to_scenario(*scenario, *results);
  if (!out.ok()) return fail(std::string(out.status().message()));
  if (auto st = write_scenarios_tfrecord(absl::GetFlag(FLAGS_out), {*out}); !st.ok()) return fail(std::string(st.message()));
  std::printf("simulated %s (%s mode, --sdc %s, seed %llu, rollout %d): %zu steps, %zu agents at the end, %zu tracks "
              "in all -> %s\n",
              scenario->id.c_str(), mode.c_str(), sdc.c_str(), static_cast<unsigned long long>(seed), rollout,
              results->size() - 1, results->back().agents.size(), out->tracks.size(), absl::GetFlag(FLAGS_out).c_str());
  return 0;
}

}  // namespace ss::cli
