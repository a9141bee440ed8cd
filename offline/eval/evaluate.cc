#include "offline/eval/evaluate.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "engine/base/rng.h"
#include "offline/eval/baselines.h"
#include "offline/eval/model_rollout.h"
#include "offline/eval/scene_features.h"
#include "offline/eval/submission.h"
#include "engine/map/focus.h"

namespace ss {
namespace {

// Per-rollout means of the MMD values that are defined.
struct MmdMean {
  InitialStateMmd sum{};
  std::array<int, 4> n{};
  void add(const InitialStateMmd& m) {
    const double v[4] = {m.position, m.heading, m.size, m.velocity};
    double* s[4] = {&sum.position, &sum.heading, &sum.size, &sum.velocity};
    for (int i = 0; i < 4; ++i)
      if (std::isfinite(v[i])) *s[i] += v[i], ++n[i];
  }
  InitialStateMmd mean() const {
    auto m = [&](double s, int k) { return k ? s / k : std::nan(""); };
    return {m(sum.position, n[0]), m(sum.heading, n[1]), m(sum.size, n[2]), m(sum.velocity, n[3])};
  }
};

void add_histograms(const SceneFeatures& log, std::span<const SceneFeatures> sims, std::span<const ObjectType> types,
                    std::array<FeatureHistogram, kNumRealismFeatures>& out) {
  for (int f = 0; f < kNumRealismFeatures; ++f) {
    const FeatureConfig& c = wosac_2025_config()[f];
    if (c.bernoulli) continue;
    const HistogramConfig fine{c.histogram.min, c.histogram.max, kPlotBins, 0};
    out[f].log.assign(kPlotBins, 0.0);
    out[f].sim.assign(kPlotBins, 0.0);
    for (size_t i = 0; i < types.size(); ++i) {
      const std::vector<uint8_t> mask = feature_mask(static_cast<RealismFeature>(f), log.valid[i], types[i]);
      for (size_t t = 0; t < mask.size(); ++t) {
        if (!mask[t]) continue;
        if (!std::isnan(log.values[f][i][t])) out[f].log[histogram_bin(fine, log.values[f][i][t])] += 1;
        for (const SceneFeatures& s : sims)
          if (!std::isnan(s.values[f][i][t])) out[f].sim[histogram_bin(fine, s.values[f][i][t])] += 1;
      }
    }
  }
}

}  // namespace

const char* eval_policy_name(EvalPolicy p) {
  switch (p) {
    case EvalPolicy::model: return "model";
    case EvalPolicy::constant_velocity: return "constant velocity";
    case EvalPolicy::log_replay: return "log replay";
    case EvalPolicy::submission: return "submission";
  }
  return "?";
}

std::vector<FrameWindow> realism_windows(int future_frames) {
  std::vector<FrameWindow> out;
  for (int w = 0; w < kNumRealismWindows; ++w) {
    const int begin = w * kRealismWindowFrames;
    if (begin >= future_frames) break;
    const int end = w + 1 == kNumRealismWindows ? future_frames : std::min(future_frames, begin + kRealismWindowFrames);
    out.push_back({begin, end});
  }
  return out;
}

const char* realism_window_name(int window) {
  static const char* const names[kNumRealismWindows] = {"0-8 s", "8-16 s", "16 s-end"};
  return window >= 0 && window < kNumRealismWindows ? names[window] : "?";
}

uint64_t rollout_seed(uint64_t base, const std::string& scenario_id, int rollout) {
  return mix_seed(mix_seed(base ^ fnv1a64(scenario_id)) + static_cast<uint64_t>(rollout));
}

absl::StatusOr<ScenarioEvaluation> evaluate_scenario(std::shared_ptr<const Scenario> scenario, const EvalOptions& options,
                                                     std::shared_ptr<const Model> model, MapCache* maps,
                                                     const std::vector<JointScene>* submitted,
                                                     std::vector<JointScene>* scenes) {
  const Scenario& s = *scenario;
  const int now = s.current_time_index;
  if (options.rollouts < 1) return absl::InvalidArgumentError("rollouts must be at least 1");
  if (now < 0 || now + 1 >= s.num_frames())
    return absl::InvalidArgumentError(
        absl::StrCat("scenario ", s.id, ": no frame after the current frame ", now, " of ", s.num_frames()));
  const std::vector<int> tracks = sim_agent_tracks(s);
  if (tracks.empty())
    return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, ": no agent is valid at the current frame ", now));
  // Under SdcRule::log a scenario whose only named track is the SDC has nothing to score: its values are undefined
  // (NaN) and the dataset means leave it out.
  const EvaluatedObjects ev = evaluated_objects(s, options.sdc);

  ScenarioEvaluation out;
  out.id = s.id;
  out.sdc = options.sdc;
  out.named_by_scenario = ev.named_by_scenario;
  out.evaluated = static_cast<int>(ev.tracks.size());
  out.future_frames = s.num_frames() - 1 - now;
  if (s.sdc_track_index >= 0) out.sdc_id = s.tracks[s.sdc_track_index].id;
  out.sim_agents = static_cast<int>(tracks.size());
  const std::vector<int> evaluated = scene_indices(tracks, ev.tracks);
  std::vector<ObjectType> types;
  for (int t : ev.tracks) types.push_back(s.tracks[t].type), out.evaluated_ids.push_back(s.tracks[t].id);
  // The SDC's place among the sim agents (-1: none, or not valid now).
  const int sdc_k = s.sdc_track_index >= 0 ? scene_indices(tracks, {s.sdc_track_index})[0] : -1;

  const EvalMap map = EvalMap::from_scenario(s);
  const JointScene log = log_scene(s, tracks);
  const SceneFeatures log_features = scene_features(log, evaluated, map, now);

  std::vector<JointScene> rollouts;
  std::vector<SceneFeatures> sims;
  if (options.policy == EvalPolicy::submission) {
    if (!submitted || submitted->empty())
      return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, ": the submission policy needs rollouts"));
    for (const JointScene& scene : *submitted) {
      if (scene.objects.size() != tracks.size() || scene.num_frames() != s.num_frames())
        return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, ": a submitted rollout does not hold its ",
                                                       tracks.size(), " sim agents over ", s.num_frames(), " frames"));
      sims.push_back(scene_features(scene, evaluated, map, now, &log, evaluated));
    }
    rollouts = *submitted;
  } else if (options.policy != EvalPolicy::model) {
    // Deterministic policies: one rollout, repeated so the estimators see the same sample size as the model's.
    JointScene scene = options.policy == EvalPolicy::constant_velocity ? constant_velocity_scene(s, tracks)
                                                                       : log_replay_scene(s, tracks);
    if (options.sdc == SdcRule::log && sdc_k >= 0) scene.objects[sdc_k] = log.objects[sdc_k];  // as an RL ego
    if (options.submission_precision) round_to_submission(scene, now);
    const SceneFeatures f = scene_features(scene, evaluated, map, now, &log, evaluated);
    rollouts.assign(options.rollouts, scene);
    sims.assign(options.rollouts, f);
  } else {
    if (!model || !maps) return absl::InvalidArgumentError("the model policy needs a model");
    auto context = maps->get(s);
    if (!context.ok())
      return absl::Status(context.status().code(), absl::StrCat("scenario ", s.id, ": ", context.status().message()));
    const bool full = options.session.mode == SessionMode::full;
    const Pose frame = mmd_frame(s);
    const std::vector<InitialAgent> log_initial = log_initial_agents(s);
    const std::vector<InitialAgent> log_strict = strict_set(log_initial, frame, s);
    MmdMean strict, relaxed;
    // The session's region: around the SDC when it is the controlled agent (--sdc log), else the scenario's focus
    // (session_create.cc); under --sdc model the model makes a stand-in for the SDC too, so the log's side counts it.
    const bool sdc_controlled = options.sdc == SdcRule::log && s.sdc_track_index >= 0;
    const ObjectState* sdc_now = sdc_controlled ? &s.tracks[s.sdc_track_index].states[now] : nullptr;
    const Vec2 centre = sdc_now ? Vec2{sdc_now->x, sdc_now->y} : scenario_focus(s);
    if (full)
      out.placed_log = log_placed_agents(s, map.road_edges, centre, options.session.roi_radius, !sdc_controlled);
    int driven = 0, filled = 0;
    double match_total = 0;
    std::optional<EgoDriver> driver;
    std::shared_ptr<const Scenario> ego_session_scenario;
    if (options.ego) {
      if (options.sdc != SdcRule::log) return absl::InvalidArgumentError("the ego benchmark needs SdcRule::log");
      auto d = EgoDriver::create(s, *options.ego);
      if (!d.ok()) return d.status();
      driver = std::move(*d);
      // The model modes see the log up to the current frame only; the rule modes replay or follow its future.
      const bool rules = options.session.mode == SessionMode::log || options.session.mode == SessionMode::idm;
      ego_session_scenario = rules ? scenario : std::make_shared<const Scenario>(history_only(s));
      out.has_ego = true;
    }
    for (int k = 0; k < options.rollouts; ++k) {
      SessionOptions o = options.session;
      o.seed = rollout_seed(options.session.seed, s.id, k);
      absl::StatusOr<std::vector<StepResult>> steps;
      if (driver) {
        EgoOutcome e;
        const int num_steps = (s.num_frames() - 1 - now + kFramesPerStep - 1) / kFramesPerStep;
        steps = run_ego_episode(model, ego_session_scenario, *context, o, *driver, num_steps, &e);
        if (!steps.ok()) return steps.status();
        EgoSummary& g = out.ego;
        ++g.episodes;
        g.collided += e.collision != EgoCollision::none;
        g.rear_end += e.collision == EgoCollision::rear_end;
        g.ego_at_fault += e.collision == EgoCollision::ego_at_fault;
        g.side += e.collision == EgoCollision::side;
        g.off_road += e.off_road;
        g.background_collision_rate +=
            e.background_agents ? static_cast<double>(e.background_collided) / e.background_agents : 0.0;
        g.outcomes.push_back(e);
      } else {
        steps = run_model_rollout(model, scenario, *context, o, options.sdc);
      }
      if (!steps.ok()) return steps.status();
      RolloutScene r = rollout_scene(s, tracks, *steps, full);
      if (options.submission_precision) round_to_submission(r.scene, now);
      driven += r.driven_frames, filled += r.filled_frames;
      out.to_match += r.to_match, out.matched += r.matched;
      match_total += r.match_distance * r.matched;
      if (full) {
        const std::vector<InitialAgent> gen = generated_initial_agents(steps->front());
        relaxed.add(initial_state_mmd(gen, log_initial, frame));
        strict.add(initial_state_mmd(strict_set(gen, frame, s), log_strict, frame));
        const PlacedAgents p = placed_agents(gen, {}, s, map.road_edges);
        out.placed_generated += p;
      }
      sims.push_back(scene_features(r.scene, evaluated, map, now, &log, evaluated));
      rollouts.push_back(std::move(r.scene));
    }
    if (out.ego.episodes) out.ego.background_collision_rate /= out.ego.episodes;
    out.filled_share = driven + filled ? static_cast<double>(filled) / (driven + filled) : 0.0;
    out.match_distance = out.matched ? match_total / out.matched : 0.0;
    if (full) out.has_mmd = true, out.mmd_strict = strict.mean(), out.mmd_relaxed = relaxed.mean();
  }

  out.rollouts = static_cast<int>(rollouts.size());
  out.realism = score_realism(log_features, sims, types);
  for (const FrameWindow& w : realism_windows(out.future_frames))
    out.windows.push_back(score_realism(log_features, sims, types, w));
  add_histograms(log_features, sims, types, out.histograms);

  // Motion metrics: every sim agent (all) and the tracks to predict; the SDC only when the policy drove it.
  const bool score_sdc = options.sdc == SdcRule::model;
  std::vector<int> all, predict;
  for (size_t k = 0; k < tracks.size(); ++k)
    if (score_sdc || tracks[k] != s.sdc_track_index) all.push_back(static_cast<int>(k));
  std::vector<int> named;
  for (const RequiredPrediction& r : s.tracks_to_predict) named.push_back(r.track_index);
  for (int t : ev.named_by_scenario ? named : ev.tracks) {
    const int k = scene_indices(tracks, {t})[0];
    if (k >= 0 && (score_sdc || t != s.sdc_track_index) && std::find(predict.begin(), predict.end(), k) == predict.end())
      predict.push_back(k);
  }
  out.motion_all = motion_metrics(log, rollouts, all, now);
  out.motion_predict = motion_metrics(log, rollouts, predict, now);
  if (scenes) *scenes = std::move(rollouts);
  return out;
}

}  // namespace ss
