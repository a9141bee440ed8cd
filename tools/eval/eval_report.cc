#include "tools/eval/eval_report.h"

#include <cmath>

#include "absl/strings/str_format.h"

namespace ss::cli {
namespace {

using nlohmann::json;

json number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

std::string policy_label(const EvalRunInfo& run) {
  if (run.policy != EvalPolicy::model) return eval_policy_name(run.policy);
  return absl::StrFormat("model (%s mode)", session_mode_name(run.mode));
}

void put_realism(json& j, const RealismScores& r) {
  j["realism_meta"] = number(r.meta);
  for (int f = 0; f < kNumRealismFeatures; ++f)
    j[std::string(wosac_2025_config()[f].name) + "_likelihood"] = number(r.likelihood[f]);
  j["kinematic"] = number(r.kinematic);
  j["interactive"] = number(r.interactive);
  j["map"] = number(r.map);
  j["collision_rate"] = number(r.collision_rate);
  j["offroad_rate"] = number(r.offroad_rate);
  j["min_ade"] = number(r.min_ade);
  j["ade"] = number(r.ade);
}

void put_motion(json& j, const MotionMetrics& m) {
  j["ade_avg"] = number(m.ade_avg);
  j["ade_min"] = number(m.ade_min);
  j["fde_avg"] = number(m.fde_avg);
  j["fde_min"] = number(m.fde_min);
  j["add"] = number(m.add);
  j["fdd"] = number(m.fdd);
}

json mmd_json(const InitialStateMmd& m) {
  return {{"position", number(m.position)}, {"heading", number(m.heading)}, {"size", number(m.size)},
          {"velocity", number(m.velocity)}};
}

std::string fmt(double v, int digits = 4) { return std::isfinite(v) ? absl::StrFormat("%.*f", digits, v) : "n/a"; }

}  // namespace

json eval_json(const EvalRunInfo& run, const DatasetEvaluation& d, std::span<const ScenarioEvaluation> scenarios) {
  json j;
  j["scenarios"] = d.scenarios;
  j["rollouts"] = run.rollouts;
  j["policy"] = eval_policy_name(run.policy);
  j["mode"] = run.policy == EvalPolicy::model ? json(session_mode_name(run.mode)) : json(nullptr);
  j["seed"] = run.seed;
  if (!run.model_path.empty()) j["model"] = run.model_path;
  put_realism(j, d.realism);
  put_motion(j, d.motion_all);
  j["motion_agents"] = d.motion_all.agents;
  json ttp;
  put_motion(ttp, d.motion_predict);
  ttp["agents"] = d.motion_predict.agents;
  j["tracks_to_predict"] = ttp;
  if (d.has_mmd) j["mmd"] = {{"strict", mmd_json(d.mmd_strict)}, {"relaxed", mmd_json(d.mmd_relaxed)}};
  j["evaluated_objects"] = {
      {"objects", d.evaluated_objects},
      {"scenarios_sdc_and_tracks_to_predict", d.named_scenarios},
      {"scenarios_every_agent_valid_now", d.scenarios - d.named_scenarios},
      {"rule", "the SDC and tracks_to_predict where the scenario names them; otherwise every agent valid at the "
               "current frame"}};
  if (run.policy == EvalPolicy::model) {
    j["model_coverage"] = {{"constant_velocity_share", number(d.filled_share)}};
    if (run.mode == SessionMode::full)
      j["model_coverage"].update({{"tracks_to_match", d.to_match},
                                  {"tracks_matched", d.matched},
                                  {"match_distance_m", number(d.match_distance)}});
  }
  json undefined = json::object();
  for (const auto& [key, n] : d.undefined) undefined[key] = n;
  j["undefined_scenarios"] = undefined;
  json per = json::array();
  for (const ScenarioEvaluation& s : scenarios) {
    json o;
    o["id"] = s.id;
    o["evaluated_objects"] = s.evaluated;
    o["evaluated_objects_named_by_scenario"] = s.named_by_scenario;
    o["sim_agents"] = s.sim_agents;
    put_realism(o, s.realism);
    put_motion(o, s.motion_all);
    if (s.has_mmd) o["mmd"] = {{"strict", mmd_json(s.mmd_strict)}, {"relaxed", mmd_json(s.mmd_relaxed)}};
    per.push_back(o);
  }
  j["per_scenario"] = per;
  return j;
}

std::string eval_table(const EvalRunInfo& run, const DatasetEvaluation& d) {
  std::string t;
  absl::StrAppendFormat(&t, "%s: %d scenarios x %d rollouts, seed %d\n", policy_label(run), d.scenarios, run.rollouts,
                        run.seed);
  absl::StrAppendFormat(&t,
                        "evaluated objects: %d (SDC + tracks_to_predict in %d scenarios; every agent valid at the "
                        "current frame in %d)\n\n",
                        d.evaluated_objects, d.named_scenarios, d.scenarios - d.named_scenarios);
  const RealismScores& r = d.realism;
  absl::StrAppendFormat(&t, "  %-30s %s\n", "realism meta-metric", fmt(r.meta));
  absl::StrAppendFormat(&t, "  %-30s %s\n  %-30s %s\n  %-30s %s\n", "kinematic", fmt(r.kinematic), "interactive",
                        fmt(r.interactive), "map", fmt(r.map));
  for (int f = 0; f < kNumRealismFeatures; ++f)
    absl::StrAppendFormat(&t, "    %-28s %s\n", wosac_2025_config()[f].name, fmt(r.likelihood[f]));
  absl::StrAppendFormat(&t, "  %-30s %s\n  %-30s %s\n  %-30s %s m\n\n", "collision rate", fmt(r.collision_rate),
                        "offroad rate", fmt(r.offroad_rate), "minADE (WOSAC)", fmt(r.min_ade));
  absl::StrAppendFormat(&t, "  %-16s %9s %9s %9s %9s %9s %9s\n", "motion (m)", "ADE avg", "ADE min", "FDE avg",
                        "FDE min", "ADD", "FDD");
  for (auto [name, m] : {std::pair{"all agents", &d.motion_all}, std::pair{"to predict", &d.motion_predict}})
    absl::StrAppendFormat(&t, "  %-16s %9s %9s %9s %9s %9s %9s\n", name, fmt(m->ade_avg, 3), fmt(m->ade_min, 3),
                          fmt(m->fde_avg, 3), fmt(m->fde_min, 3), fmt(m->add, 3), fmt(m->fdd, 3));
  if (d.has_mmd) {
    absl::StrAppendFormat(&t, "\n  %-16s %9s %9s %9s %9s\n", "initial MMD", "position", "heading", "size", "velocity");
    for (auto [name, m] : {std::pair{"strict", &d.mmd_strict}, std::pair{"relaxed", &d.mmd_relaxed}})
      absl::StrAppendFormat(&t, "  %-16s %9s %9s %9s %9s\n", name, fmt(m->position), fmt(m->heading), fmt(m->size),
                            fmt(m->velocity));
  }
  if (run.policy == EvalPolicy::model) {
    absl::StrAppendFormat(&t, "\n  sim-agent frames moved at constant velocity (not driven by the model): %s%%\n",
                          fmt(100 * d.filled_share, 1));
    if (run.mode == SessionMode::full)
      absl::StrAppendFormat(&t, "  tracks paired with a generated agent: %d of %d (mean distance %s m)\n", d.matched,
                            d.to_match, fmt(d.match_distance, 1));
  }
  for (const auto& [key, n] : d.undefined)
    absl::StrAppendFormat(&t, "  note: %s undefined in %d scenario(s), averaged over the others\n", key, n);
  return t;
}

}  // namespace ss::cli
