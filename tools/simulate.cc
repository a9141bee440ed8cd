// scenestreamer simulate --scenario FILE --model W --mode motion|full|densify --steps N --seed S --out FILE
#include <cstdio>

#include "absl/strings/numbers.h"
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
    "usage: scenestreamer simulate --scenario FILE --model WEIGHTS --out OUT.tfrecord\n"
    "                              [--mode motion|full|densify] [--steps N] [--seed S] [--index I]\n"
    "                              [--top-p P] [--temperature T] [--max-agents N] [--densify-target N]\n"
    "  Rolls the scenario out from its current step for N model steps (0.5 s each; default 16, to the end of a WOMD\n"
    "  scenario) and writes it as a 10 Hz WOMD Scenario TFRecord. The SDC replays its logged poses while the log lasts\n"
    "  (then keeps its last control); --free-sdc lets the model drive it too.\n";

int fail(const std::string& msg) {
  std::fprintf(stderr, "simulate: %s\n", msg.c_str());
  return 1;
}

}  // namespace

int simulate_main(int argc, char** argv) {
  auto args = parse_args(argc, argv, 1,
                         {"scenario", "model", "mode", "steps", "seed", "out", "index", "top-p", "temperature",
                          "max-agents", "densify-target"},
                         {"help", "free-sdc"});
  if (!args.ok() || args->has("help") || !args->positional.empty() || !args->has("scenario") ||
      !args->has("model") || !args->has("out")) {
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
  int steps = 16, index = 0;
  auto number = [&](const char* flag, auto* out) {
    if (!args->has(flag)) return true;
    using T = std::remove_pointer_t<decltype(out)>;
    bool ok;
    if constexpr (std::is_floating_point_v<T>) ok = absl::SimpleAtod(args->get(flag), out);
    else ok = absl::SimpleAtoi(args->get(flag), out);
    if (!ok) std::fprintf(stderr, "simulate: --%s '%s' is not a number\n", flag, args->get(flag).c_str());
    return ok;
  };
  if (!number("steps", &steps) || !number("seed", &o.seed) || !number("index", &index) || !number("top-p", &o.top_p) ||
      !number("temperature", &o.temperature) || !number("max-agents", &o.max_agents) ||
      !number("densify-target", &o.densify_target))
    return 2;
  if (steps < 0 || steps > 100000) return fail("--steps must be in 0..100000");

  enable_flush_to_zero();
  auto weights = load_weights(args->get("model"));
  if (!weights.ok()) return fail(std::string(weights.status().message()));
  auto model = Model::create(std::move(*weights));
  if (!model.ok()) return fail(std::string(model.status().message()));
  auto scenarios = read_scenarios(args->get("scenario"));
  if (!scenarios.ok()) return fail(std::string(scenarios.status().message()));
  if (index < 0 || index >= static_cast<int>(scenarios->size()))
    return fail("--index " + std::to_string(index) + " is outside the file's " + std::to_string(scenarios->size()) +
                " scenarios");
  auto scenario = std::make_shared<const Scenario>((*scenarios)[index]);
  o.control_sdc = !args->has("free-sdc");
  MapCache maps(*model);
  auto map = maps.get(*scenario);
  if (!map.ok()) return fail(std::string(map.status().message()));
  auto session = Session::create(*model, scenario, *map, o);
  if (!session.ok()) return fail(std::string(session.status().message()));

  std::vector<StepResult> results = {(*session)->current()};
  const Track* sdc = scenario->sdc_track_index >= 0 ? &scenario->tracks[scenario->sdc_track_index] : nullptr;
  for (int i = 0; i < steps; ++i) {
    std::vector<ControlInput> controls;
    const int frame = ((*session)->step_index() + 1) * kFramesPerStep;
    if (sdc && o.control_sdc && frame < static_cast<int>(sdc->states.size()) && sdc->states[frame].valid) {
      const bool controlled = std::any_of(results.back().agents.begin(), results.back().agents.end(),
                                          [&](const AgentView& a) { return a.id == sdc->id && a.controlled; });
      if (controlled) {
        const ObjectState& st = sdc->states[frame];
        controls.push_back({sdc->id, st.x, st.y, st.heading, std::nullopt});
      }
    }
    auto r = (*session)->step(controls);
    if (!r.ok()) return fail("step " + std::to_string(i + 1) + ": " + std::string(r.status().message()));
    results.push_back(std::move(*r));
  }
  const Scenario rollout = rollout_to_scenario(*scenario, results);
  if (auto st = write_scenarios_tfrecord(args->get("out"), {rollout}); !st.ok()) return fail(std::string(st.message()));
  std::printf("simulated %s (%s mode, seed %llu): %d steps, %zu agents at the end, %zu tracks in all -> %s\n",
              scenario->id.c_str(), mode.c_str(), static_cast<unsigned long long>(o.seed), steps,
              results.back().agents.size(), rollout.tracks.size(), args->get("out").c_str());
  return 0;
}

}  // namespace ss::cli
