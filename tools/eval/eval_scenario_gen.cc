#include "tools/eval/eval_scenario_gen.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "engine/io/json_text.h"
#include "spdlog/spdlog.h"

namespace ss::cli {
namespace {

int fail(const std::string& msg) {
  spdlog::error("eval: {}", msg);
  return 1;
}

nlohmann::ordered_json realism_json(const RealismScores& r) {
  nlohmann::ordered_json j;
  j["meta"] = r.meta;
  j["kinematic"] = r.kinematic;
  j["interactive"] = r.interactive;
  j["map"] = r.map;
  for (int f = 0; f < kNumRealismFeatures; ++f)
    j[absl::StrCat(wosac_2025_config()[f].name, "_likelihood")] = r.likelihood[f];
  j["collision_rate"] = r.collision_rate;
  j["offroad_rate"] = r.offroad_rate;
  return j;
}

nlohmann::ordered_json mmd_json(const InitialStateMmd& m) {
  return {{"position", m.position}, {"heading", m.heading}, {"size", m.size}, {"velocity", m.velocity}};
}

nlohmann::ordered_json placed_json(const PlacedAgents& p) {
  return {{"agents", p.agents},
          {"vehicles", p.vehicles},
          {"offroad_vehicles", p.offroad_vehicles},
          {"offroad_share", offroad_share(p)},
          {"standing_share", standing_share(p)},
          {"mean_vehicle_speed", mean_vehicle_speed(p)}};
}

}  // namespace

int run_scenario_gen(ScenarioGenRun& run) {
  const auto& all = run.scenarios;
  for (const auto& s : all)
    if (const std::string p = scenario_gen_problem(*s); !p.empty()) return fail(absl::StrCat("scenario ", s->id, ": ", p));
  // The submission policy: each log's scenes, matched by scenario id in both directions.
  std::vector<std::vector<JointScene>> submitted(all.size());
  if (run.options.policy == ScenarioGenPolicy::submission) {
    auto read = read_submission({run.submission_in});
    if (!read.ok()) return fail(std::string(read.status().message()));
    std::map<std::string, const ScenarioRollouts*> by_id;
    for (const ScenarioRollouts& r : read->rollouts) by_id[r.scenario_id] = &r;
    for (size_t i = 0; i < all.size(); ++i) {
      auto it = by_id.find(all[i]->id);
      if (it == by_id.end()) return fail(absl::StrCat("--submission has no rollouts of scenario ", all[i]->id, " (in --data)"));
      auto scenes = scenegen_scenes_from_rollouts(*all[i], *it->second, run.submission_in);
      if (!scenes.ok()) return fail(std::string(scenes.status().message()));
      submitted[i] = std::move(*scenes);
      by_id.erase(it);
    }
    if (!by_id.empty())
      return fail(absl::StrCat("--submission has ", by_id.size(), " scenario(s) that --data does not, e.g. ",
                               by_id.begin()->first));
  }
  const bool write = !run.submission_out.empty();
  std::unique_ptr<MapCache> maps = run.model ? std::make_unique<MapCache>(run.model) : nullptr;
  std::vector<std::optional<absl::StatusOr<ScenarioGenEvaluation>>> results(all.size());
  std::vector<std::optional<ScenarioRollouts>> to_write(all.size());
  std::atomic<size_t> next{0};
  std::mutex log_mu;
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&] {
    for (size_t i = next++; i < all.size(); i = next++) {
      std::vector<JointScene> scenes;
      results[i] = evaluate_scenario_gen(all[i], run.options, run.model, maps.get(),
                                         submitted[i].empty() ? nullptr : &submitted[i], write ? &scenes : nullptr);
      if (write && results[i]->ok()) {
        auto r = scenegen_rollouts_from_scenes(*all[i], scenes);
        if (!r.ok()) results[i] = r.status();
        else to_write[i] = std::move(*r);
      }
      const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::lock_guard<std::mutex> lock(log_mu);
      spdlog::info("eval: {} {} ({:.0f} s)", all[i]->id, results[i]->ok() ? "done" : "failed", secs);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::min<int>(run.threads, static_cast<int>(all.size())); ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();
  std::vector<ScenarioGenEvaluation> evaluations;
  for (auto& r : results) {
    if (!r->ok()) return fail(std::string(r->status().message()));
    evaluations.push_back(std::move(**r));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (write) {
    std::error_code ec;
    std::filesystem::create_directories(run.submission_out, ec);
    if (ec) return fail(absl::StrCat("cannot create --wosac-submission ", run.submission_out, ": ", ec.message()));
    std::vector<ScenarioRollouts> rollouts;
    for (auto& r : to_write) rollouts.push_back(std::move(*r));
    if (auto st = write_submission(run.submission_out, rollouts, run.metadata); !st.ok())
      return fail(std::string(st.message()));
  }

  const ScenarioGenDataset d = aggregate_scenario_gen(evaluations);
  nlohmann::ordered_json j;
  j["protocol"] = "scenario-gen";
  j["policy"] = scenario_gen_policy_name(run.options.policy);
  if (run.options.policy == ScenarioGenPolicy::model) {
    j["model"] = run.model_path;
    j["seed"] = run.options.session.seed;
    j["top_p"] = run.options.session.top_p;
    j["temperature"] = run.options.session.temperature;
    j["motion_reject"] = run.options.session.motion_reject;
    j["roi_radius"] = run.options.session.roi_radius;
    j["placement_temperature"] = run.options.session.placement_temperature;
    j["placement_top_p"] = run.options.session.placement_top_p;
    j["placement_clearance"] = run.options.session.placement_clearance;
    j["placement_room"] = run.options.session.placement_room;
    j["pedestrian_contact"] = run.options.session.pedestrian_contact;
    j["history"] = scenario_gen_history_name(run.options.history);
  }
  if (run.options.policy == ScenarioGenPolicy::placement) j["seed"] = run.options.session.seed;
  j["rollouts"] = d.rollouts;
  j["scenarios"] = d.scenarios;
  j["seconds"] = seconds;
  j["realism"] = realism_json(d.realism);
  j["mmd_strict"] = mmd_json(d.mmd_strict);
  j["mmd_relaxed"] = mmd_json(d.mmd_relaxed);
  j["mmd_pooled_strict"] = mmd_json(d.mmd_pooled_strict);
  j["mmd_pooled_relaxed"] = mmd_json(d.mmd_pooled_relaxed);
  j["rollouts_with_exact_counts"] = d.exact_rollouts;
  j["rollouts_with_overlap_at_current_frame"] = d.overlapping_rollouts;
  j["total_rollouts"] = d.total_rollouts;
  j["agents_placed_by_rule"] = d.filled;
  j["placed_log"] = placed_json(d.placed_log);
  j["placed_generated"] = placed_json(d.placed_generated);
  nlohmann::ordered_json per = nlohmann::ordered_json::array();
  for (const ScenarioGenEvaluation& e : evaluations) {
    nlohmann::ordered_json s;
    s["id"] = e.id;
    s["sim_agents"] = e.sim_agents;
    s["requested"] = {e.requested[0], e.requested[1], e.requested[2]};
    s["realism"] = realism_json(e.realism);
    s["mmd_strict"] = mmd_json(e.mmd_strict);
    s["mmd_relaxed"] = mmd_json(e.mmd_relaxed);
    s["mmd_pooled_strict"] = mmd_json(e.mmd_pooled_strict);
    s["mmd_pooled_relaxed"] = mmd_json(e.mmd_pooled_relaxed);
    s["rollouts_with_exact_counts"] = e.exact_rollouts;
    s["rollouts_with_overlap_at_current_frame"] = e.overlapping_rollouts;
    s["agents_placed_by_rule"] = e.filled;
    per.push_back(std::move(s));
  }
  j["per_scenario"] = std::move(per);
  const std::string text = json_text(j) + "\n";
  if (run.json_out == "-") {
    std::fputs(text.c_str(), stdout);
  } else {
    std::ofstream f(run.json_out, std::ios::binary | std::ios::trunc);
    f << text;
    f.close();
    if (!f) return fail("cannot write --json " + run.json_out);
  }
  std::FILE* out = run.json_out == "-" ? stderr : stdout;
  std::string t = absl::StrFormat(
      "scenario generation (%s), %d scenarios x %d rollouts (%.0f s)\n"
      "  meta-metric %.4f   kinematic %.4f  interactive %.4f  map %.4f\n"
      "  collision rate %.4f  offroad rate %.4f\n",
      scenario_gen_policy_name(run.options.policy), d.scenarios, d.rollouts, seconds, d.realism.meta, d.realism.kinematic,
      d.realism.interactive, d.realism.map, d.realism.collision_rate, d.realism.offroad_rate);
  for (int f = 0; f < kNumRealismFeatures; ++f)
    t += absl::StrFormat("  %-28s %.4f\n", wosac_2025_config()[f].name, d.realism.likelihood[f]);
  t += absl::StrFormat("  initial-state MMD (strict): position %.4f heading %.4f size %.4f velocity %.4f\n",
                       d.mmd_strict.position, d.mmd_strict.heading, d.mmd_strict.size, d.mmd_strict.velocity);
  t += absl::StrFormat("  initial-state MMD (relaxed): position %.4f heading %.4f size %.4f velocity %.4f\n",
                       d.mmd_relaxed.position, d.mmd_relaxed.heading, d.mmd_relaxed.size, d.mmd_relaxed.velocity);
  t += absl::StrFormat("  initial-state MMD, rollouts pooled (strict): position %.4f heading %.4f size %.4f velocity %.4f\n",
                       d.mmd_pooled_strict.position, d.mmd_pooled_strict.heading, d.mmd_pooled_strict.size,
                       d.mmd_pooled_strict.velocity);
  t += absl::StrFormat("  initial-state MMD, rollouts pooled (relaxed): position %.4f heading %.4f size %.4f velocity %.4f\n",
                       d.mmd_pooled_relaxed.position, d.mmd_pooled_relaxed.heading, d.mmd_pooled_relaxed.size,
                       d.mmd_pooled_relaxed.velocity);
  t += absl::StrFormat("  counts exact in %d of %d rollouts; boxes overlapping at the current frame in %d; %d agents "
                       "placed by rule (no model slot left)\n",
                       d.exact_rollouts, d.total_rollouts, d.overlapping_rollouts, d.filled);
  t += absl::StrFormat("  offroad share of vehicles at the current frame: generated %.4f (%d of %d), log %.4f (%d of %d)\n",
                       offroad_share(d.placed_generated), d.placed_generated.offroad_vehicles,
                       d.placed_generated.vehicles, offroad_share(d.placed_log), d.placed_log.offroad_vehicles,
                       d.placed_log.vehicles);
  t += absl::StrFormat("  vehicles standing (below %.1f m/s) at the current frame: generated %.4f, log %.4f; mean speed "
                       "generated %.2f m/s, log %.2f m/s\n",
                       kStandingSpeed, standing_share(d.placed_generated), standing_share(d.placed_log),
                       mean_vehicle_speed(d.placed_generated), mean_vehicle_speed(d.placed_log));
  if (write) t += absl::StrFormat("  submission: %zu scenarios in %s\n", evaluations.size(), run.submission_out);
  std::fputs(t.c_str(), out);
  return 0;
}

}  // namespace ss::cli
