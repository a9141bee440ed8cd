#include "tools/eval/eval_report.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "absl/strings/str_format.h"

namespace ss::cli {
namespace {

using nlohmann::json;

std::string policy_label(const EvalRunInfo& run) {
  if (run.policy != EvalPolicy::model) return eval_policy_name(run.policy);
  if (run.mode == SessionMode::log || run.mode == SessionMode::idm)
    return absl::StrFormat("%s mode (rule baseline, no model)", session_mode_name(run.mode));
  return absl::StrFormat("model (%s mode, top-p %g, temperature %g, motion reject sampling %s)",
                         session_mode_name(run.mode), run.top_p, run.temperature, run.motion_reject ? "on" : "off");
}

void put_realism(json& j, const RealismScores& r) {
  j["realism_meta"] = r.meta;
  for (int f = 0; f < kNumRealismFeatures; ++f)
    j[std::string(wosac_2025_config()[f].name) + "_likelihood"] = r.likelihood[f];
  j.update({{"kinematic", r.kinematic}, {"interactive", r.interactive}, {"map", r.map},
            {"collision_rate", r.collision_rate}, {"offroad_rate", r.offroad_rate}, {"min_ade", r.min_ade},
            {"ade", r.ade}});
}

void put_motion(json& j, const MotionMetrics& m) {
  j.update({{"ade_avg", m.ade_avg}, {"ade_min", m.ade_min}, {"fde_avg", m.fde_avg}, {"fde_min", m.fde_min},
            {"add", m.add}, {"fdd", m.fdd}});
}

// Counts divided by `rollouts` (the generated side is summed over them), the offroad share of the vehicles, and how
// many of them stand.
json placed_json(const PlacedAgents& p, int rollouts) {
  const double k = std::max(rollouts, 1);
  return {{"agents", p.agents / k}, {"vehicles", p.vehicles / k}, {"offroad_vehicles", p.offroad_vehicles / k},
          {"offroad_rate", offroad_share(p)}, {"standing_share", standing_share(p)},
          {"mean_vehicle_speed", mean_vehicle_speed(p)}};
}

json mmd_json(const InitialStateMmd& m) {
  return {{"position", m.position}, {"heading", m.heading}, {"size", m.size}, {"velocity", m.velocity}};
}

json windows_json(std::span<const RealismScores> windows, std::span<const int> scenarios = {}) {
  json out = json::array();
  for (size_t w = 0; w < windows.size(); ++w) {
    json o;
    o["window"] = realism_window_name(static_cast<int>(w));
    o["from_s"] = static_cast<int>(w) * kRealismWindowFrames / 10;
    o["to_s"] = w + 1 < kNumRealismWindows ? json(static_cast<int>(w + 1) * kRealismWindowFrames / 10) : json(nullptr);
    if (!scenarios.empty()) o["scenarios"] = scenarios[w];
    o["objects"] = windows[w].objects;
    put_realism(o, windows[w]);
    out.push_back(o);
  }
  return out;
}

const char* sdc_rule_text(SdcRule r) {
  return r == SdcRule::model ? "the policy drives the SDC like every other agent, and the SDC is evaluated (WOSAC)"
                             : "the SDC follows its log (as an RL ego would) and is left out of the evaluated objects";
}

// Episode shares of the ego benchmark: each kind over the episodes.
json ego_json(const EgoSummary& e) {
  const double n = e.episodes > 0 ? e.episodes : std::numeric_limits<double>::quiet_NaN();
  return {{"episodes", e.episodes},
          {"collision", e.collided / n},
          {"rear_end", e.rear_end / n},
          {"ego_at_fault", e.ego_at_fault / n},
          {"side", e.side / n},
          {"background_fault", (e.rear_end + e.side) / n},
          {"off_road", e.off_road / n},
          {"background_collision_rate", e.background_collision_rate}};
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
  j["sdc"] = sdc_rule_name(run.sdc);
  j["sdc_rule"] = sdc_rule_text(run.sdc);
  if (!run.model_path.empty()) j["model"] = run.model_path;
  j["ego"] = run.ego ? json(ego_policy_name(*run.ego)) : json(nullptr);
  if (d.has_ego) {
    j["ego_outcome"] = ego_json(d.ego);
    j["ego_outcome"]["scenarios_without_sdc_left_out"] = run.no_ego;
  }
  if (run.policy == EvalPolicy::model) j["sampling"] = {{"top_p", run.top_p}, {"temperature", run.temperature}, {"motion_reject", run.motion_reject}};
  put_realism(j, d.realism);
  std::vector<RealismScores> windows;
  std::vector<int> window_scenarios;
  for (const DatasetEvaluation::Window& w : d.windows) windows.push_back(w.realism), window_scenarios.push_back(w.scenarios);
  j["windows"] = windows_json(windows, window_scenarios);
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
      {"rule", run.sdc == SdcRule::model
                   ? "the SDC and tracks_to_predict where the scenario names tracks to predict; otherwise every "
                     "agent valid at the current frame"
                   : "tracks_to_predict where the scenario names them; otherwise every agent valid at the current "
                     "frame; never the SDC (--sdc log)"}};
  if (run.policy == EvalPolicy::model) {
    j["model_coverage"] = {{"constant_velocity_share", d.filled_share}};
    if (run.mode == SessionMode::full)
      j["model_coverage"].update({{"tracks_to_match", d.to_match},
                                  {"tracks_matched", d.matched},
                                  {"match_distance_m", d.match_distance}});
  }
  if (d.has_mmd)
    j["placed_agents"] = {{"log", placed_json(d.placed_log, 1)},
                          {"generated_per_rollout", placed_json(d.placed_generated, run.rollouts)},
                          {"scenarios_count_within_30pct", d.placed_within_30},
                          {"scenarios_with_log_agents", d.placed_scenarios},
                          {"count_correlation", d.placed_count_correlation}};
  json undefined = json::object();
  for (const auto& [key, n] : d.undefined) undefined[key] = n;
  j["undefined_scenarios"] = undefined;
  json per = json::array();
  for (const ScenarioEvaluation& s : scenarios) {
    json o;
    o["id"] = s.id;
    o["evaluated_objects"] = s.evaluated;
    o["evaluated_objects_named_by_scenario"] = s.named_by_scenario;
    o["evaluated_ids"] = s.evaluated_ids;
    o["sdc_id"] = s.sdc_id >= 0 ? json(s.sdc_id) : json(nullptr);
    o["sdc_evaluated"] = std::find(s.evaluated_ids.begin(), s.evaluated_ids.end(), s.sdc_id) != s.evaluated_ids.end();
    o["sim_agents"] = s.sim_agents;
    o["future_frames"] = s.future_frames;
    put_realism(o, s.realism);
    put_motion(o, s.motion_all);
    json ttp;
    put_motion(ttp, s.motion_predict);
    ttp["agents"] = s.motion_predict.agents;
    o["tracks_to_predict"] = ttp;
    if (run.policy == EvalPolicy::model) o["model_driven_share"] = 1 - s.filled_share;
    o["windows"] = windows_json(s.windows);
    if (s.has_ego) {
      o["ego_outcome"] = ego_json(s.ego);
      json episodes = json::array();
      for (const EgoOutcome& e : s.ego.outcomes)
        episodes.push_back({{"collision", ego_collision_name(e.collision)},
                            {"collision_step", e.collision_step >= 0 ? json(e.collision_step) : json(nullptr)},
                            {"collision_with", e.collision_with >= 0 ? json(e.collision_with) : json(nullptr)},
                            {"off_road", e.off_road}});
      o["ego_episodes"] = episodes;
    }
    if (s.has_mmd) {
      o["mmd"] = {{"strict", mmd_json(s.mmd_strict)}, {"relaxed", mmd_json(s.mmd_relaxed)}};
      o["placed_agents"] = {{"log", placed_json(s.placed_log, 1)},
                            {"generated_per_rollout", placed_json(s.placed_generated, s.rollouts)}};
    }
    per.push_back(o);
  }
  j["per_scenario"] = per;
  return j;
}

std::string eval_table(const EvalRunInfo& run, const DatasetEvaluation& d) {
  std::string t;
  absl::StrAppendFormat(&t, "%s: %d scenarios x %d rollouts, seed %d\n", policy_label(run), d.scenarios, run.rollouts,
                        run.seed);
  absl::StrAppendFormat(&t, "SDC: --sdc %s: %s\n", sdc_rule_name(run.sdc), sdc_rule_text(run.sdc));
  absl::StrAppendFormat(&t,
                        "evaluated objects: %d (%stracks_to_predict in %d scenarios; every agent valid at the "
                        "current frame%s in %d)\n\n",
                        d.evaluated_objects, run.sdc == SdcRule::model ? "SDC + " : "", d.named_scenarios,
                        run.sdc == SdcRule::model ? "" : " but the SDC", d.scenarios - d.named_scenarios);
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
  // Per window, when some scenario is longer than one window (a 91-frame scenario's only window is the whole).
  if (d.windows.size() > 1) {
    absl::StrAppendFormat(&t, "\n  %-10s %9s %9s %9s %9s %9s %9s %9s %9s %9s\n", "window", "scenarios", "objects",
                          "realism", "kinematic", "interact.", "map", "collision", "offroad", "minADE");
    for (size_t w = 0; w < d.windows.size(); ++w) {
      const RealismScores& x = d.windows[w].realism;
      absl::StrAppendFormat(&t, "  %-10s %9d %9d %9s %9s %9s %9s %9s %9s %9s\n", realism_window_name(static_cast<int>(w)),
                            d.windows[w].scenarios, x.objects, fmt(x.meta), fmt(x.kinematic), fmt(x.interactive),
                            fmt(x.map), fmt(x.collision_rate, 3), fmt(x.offroad_rate, 3), fmt(x.min_ade, 3));
    }
    absl::StrAppendFormat(&t, "  (objects: those the log has in the window; the window's minADE counts its own frames)\n");
  }
  if (d.has_mmd) {
    absl::StrAppendFormat(&t, "\n  %-16s %9s %9s %9s %9s\n", "initial MMD", "position", "heading", "size", "velocity");
    for (auto [name, m] : {std::pair{"strict", &d.mmd_strict}, std::pair{"relaxed", &d.mmd_relaxed}})
      absl::StrAppendFormat(&t, "  %-16s %9s %9s %9s %9s\n", name, fmt(m->position), fmt(m->heading), fmt(m->size),
                            fmt(m->velocity));
    const double per_rollout = run.rollouts > 0 ? static_cast<double>(d.placed_generated.agents) / run.rollouts : 0;
    absl::StrAppendFormat(&t, "\n  agents in the region at the first step: generated %s per rollout, log %d; "
                          "scenarios within 30 %% of the log's count: %d of %d; correlation of the counts: %s\n",
                          fmt(per_rollout, 1), d.placed_log.agents, d.placed_within_30, d.placed_scenarios,
                          fmt(d.placed_count_correlation, 2));
    absl::StrAppendFormat(&t, "  offroad vehicles at the first step: generated %s (%d of %d), log %s (%d of %d)\n",
                          fmt(offroad_share(d.placed_generated), 3), d.placed_generated.offroad_vehicles,
                          d.placed_generated.vehicles, fmt(offroad_share(d.placed_log), 3),
                          d.placed_log.offroad_vehicles, d.placed_log.vehicles);
  }
  if (d.has_ego) {
    const EgoSummary& e = d.ego;
    const auto share = [&](int k) { return absl::StrFormat("%s (%d of %d)", fmt(e.episodes ? double(k) / e.episodes : NAN, 3), k, e.episodes); };
    absl::StrAppendFormat(&t, "\n  ego --ego %s: episodes with an ego collision %s\n", ego_policy_name(*run.ego),
                          share(e.collided));
    if (run.no_ego) absl::StrAppendFormat(&t, "    (%d scenario(s) without an SDC left out)\n", run.no_ego);
    absl::StrAppendFormat(&t, "    rear-end (another ran into it from behind) %s; ego at fault %s; side or crossing %s\n",
                          share(e.rear_end), share(e.ego_at_fault), share(e.side));
    absl::StrAppendFormat(&t, "    the background's fault (rear-end + side) %s; ego off road %s\n",
                          share(e.rear_end + e.side), share(e.off_road));
    absl::StrAppendFormat(&t, "    background agents colliding with each other: %s per episode (mean share)\n",
                          fmt(e.background_collision_rate, 4));
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
