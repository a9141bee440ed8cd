// Starting a session from a scenario: the log's history up to the current step is teacher-forced, then the model
// samples what the mode leaves open.
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "engine/map/focus.h"
#include "engine/sim/session.h"
#include "engine/tokens/fidelity.h"

namespace ss {
namespace {

absl::Status check_options(const SessionOptions& o, const ModelConfig& c) {
  const int mode = static_cast<int>(o.mode);
  if (mode < 0 || mode > 4)
    return absl::InvalidArgumentError(absl::StrCat("options.mode ", mode, " is not motion, full, densify, log or idm"));
  if (!(o.temperature > 0) || !std::isfinite(o.temperature))
    return absl::InvalidArgumentError(absl::StrCat("options.temperature ", o.temperature, " must be positive"));
  if (!(o.top_p > 0 && o.top_p <= 1)) return absl::InvalidArgumentError(absl::StrCat("options.top_p ", o.top_p, " must be in (0, 1]"));
  if (o.max_agents < 1 || o.max_agents > c.agent_slots)
    return absl::InvalidArgumentError(absl::StrCat("options.max_agents ", o.max_agents, " is outside 1..", c.agent_slots));
  if (!(o.roi_radius > 0) || !std::isfinite(o.roi_radius))
    return absl::InvalidArgumentError(absl::StrCat("options.roi_radius ", o.roi_radius, " must be positive"));
  if (o.window_steps != 0 && (o.window_steps < 2 || o.window_steps > c.window_steps))
    return absl::InvalidArgumentError(absl::StrCat("options.window_steps ", o.window_steps, " is outside 2..", c.window_steps,
                                                   " (0: the model's)"));
  if (o.tick_hz != 2 && o.tick_hz != 10)
    return absl::InvalidArgumentError(absl::StrCat("tick_hz ", o.tick_hz, ": only 2 or 10"));
  if (o.densify_target < 0 || o.densify_target > o.max_agents)
    return absl::InvalidArgumentError(absl::StrCat("options.densify_target ", o.densify_target, " is outside 0..max_agents"));
  if (!(o.placement_temperature > 0) || !std::isfinite(o.placement_temperature))
    return absl::InvalidArgumentError(absl::StrCat("options.placement_temperature ", o.placement_temperature,
                                                   " must be positive"));
  if (!(o.placement_top_p > 0 && o.placement_top_p <= 1))
    return absl::InvalidArgumentError(absl::StrCat("options.placement_top_p ", o.placement_top_p, " must be in (0, 1]"));
  if (!(o.placement_clearance >= 0 && o.placement_clearance <= 10))
    return absl::InvalidArgumentError(absl::StrCat("options.placement_clearance ", o.placement_clearance,
                                                   " is outside 0..10 m"));
  if (!o.agent_counts.empty()) {
    if (o.mode != SessionMode::full)
      return absl::InvalidArgumentError(absl::StrCat("options.agent_counts: only full mode places agents by count (mode ",
                                                     session_mode_name(o.mode), ")"));
    if (o.agent_counts.size() != kAgentTypes)
      return absl::InvalidArgumentError(absl::StrCat("options.agent_counts has ", o.agent_counts.size(),
                                                     " entries; it needs ", kAgentTypes,
                                                     " (vehicles, pedestrians, cyclists)"));
    int total = 0;
    for (size_t t = 0; t < o.agent_counts.size(); ++t) {
      if (o.agent_counts[t] < 0 || o.agent_counts[t] > o.max_agents)
        return absl::InvalidArgumentError(absl::StrCat("options.agent_counts[", t, "] ", o.agent_counts[t],
                                                       " is outside 0..max_agents (", o.max_agents, ")"));
      total += o.agent_counts[t];
    }
    if (total > o.max_agents)
      return absl::InvalidArgumentError(absl::StrCat("options.agent_counts sum to ", total, ", more than max_agents (",
                                                     o.max_agents, ")"));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::unique_ptr<Session>> Session::create(std::shared_ptr<const Model> model,
                                                         std::shared_ptr<const Scenario> scenario,
                                                         std::shared_ptr<const MapContext> map, SessionOptions options,
                                                         Probe* probe) {
  if (auto st = check_options(options, model->config()); !st.ok()) return st;
  if (!map || map->size() == 0) return absl::FailedPreconditionError("the scenario's map has no segments");
  const int now_frame = scenario->current_time_index;
  const int t0 = now_frame / kFramesPerStep;

  auto s = std::unique_ptr<Session>(new Session());
  s->model_ = std::move(model);
  s->scenario_ = scenario;
  s->map_ = std::move(map);
  s->options_ = options;
  s->probe_ = probe;
  s->rng_ = Rng(options.seed);
  s->cache_ = s->model_->new_cache();
  s->slot_used_.assign(s->model_->config().agent_slots, false);
  for (const Track& t : scenario->tracks) s->next_agent_id_ = std::max<int64_t>(s->next_agent_id_, t.id + 1);

  // Controlled agents: the caller's, or the SDC.
  std::vector<int32_t> controlled = options.controlled_ids;
  if (controlled.empty() && options.control_sdc && scenario->sdc_track_index >= 0 &&
      scenario->tracks[scenario->sdc_track_index].states[now_frame].valid)
    controlled.push_back(scenario->tracks[scenario->sdc_track_index].id);
  auto track_index = [&](int32_t id) {
    for (size_t i = 0; i < scenario->tracks.size(); ++i)
      if (scenario->tracks[i].id == id) return static_cast<int>(i);
    return -1;
  };
  std::vector<int> chosen;
  for (int32_t id : controlled) {
    const int i = track_index(id);
    if (i < 0) return absl::InvalidArgumentError(absl::StrCat("controlled agent ", id, ": no such track in scenario ", scenario->id));
    if (model_type(scenario->tracks[i].type) < 0)
      return absl::InvalidArgumentError(absl::StrCat("controlled agent ", id, ": type ", object_type_name(scenario->tracks[i].type),
                                                     " is not a vehicle, pedestrian or cyclist"));
    if (!scenario->tracks[i].states[now_frame].valid)
      return absl::InvalidArgumentError(absl::StrCat("controlled agent ", id, ": not valid at the current frame ", now_frame));
    if (std::find(chosen.begin(), chosen.end(), i) != chosen.end())
      return absl::InvalidArgumentError(absl::StrCat("controlled agent ", id, ": listed twice"));
    chosen.push_back(i);
  }
  const size_t num_controlled = chosen.size();
  if (static_cast<int>(num_controlled) > options.max_agents)
    return absl::InvalidArgumentError("more controlled agents than options.max_agents");
  // Placement by count: the ego's state is given (the SDC's, from the log), the model drives it unless controlled.
  const bool by_count = !options.agent_counts.empty();
  if (by_count && scenario->sdc_track_index >= 0 && scenario->tracks[scenario->sdc_track_index].states[now_frame].valid &&
      model_type(scenario->tracks[scenario->sdc_track_index].type) >= 0 &&
      std::find(chosen.begin(), chosen.end(), scenario->sdc_track_index) == chosen.end())
    chosen.push_back(scenario->sdc_track_index);
  if (by_count) {
    int total = static_cast<int>(chosen.size());
    for (int n : options.agent_counts) total += n;
    if (total > options.max_agents)
      return absl::InvalidArgumentError(absl::StrCat("options.agent_counts and the ", chosen.size(),
                                                     " agents taken from the log make ", total,
                                                     ", more than max_agents (", options.max_agents, ")"));
  }

  // Lights: the lanes with a signal state at the current frame, by lane id, anchored on their lane's segment.
  for (const TokenLight& tl : scenario_lights(*scenario, now_frame, s->map_->segments, s->map_->index,
                                              s->model_->config().light_slots)) {
    Light l;
    l.lane = tl.lane;
    l.map_id = tl.map_id;
    l.pose = tl.pose;
    s->lights_.push_back(l);
  }

  if (s->rule_mode()) {
    // No tokens: the controlled agents, then every log agent valid at the current frame (no region of interest: a
    // log replay shows the whole log), each at its logged state.
    auto paths = std::make_shared<std::vector<LoggedPath>>();
    for (const Track& t : scenario->tracks) paths->push_back(logged_path(t));
    s->paths_ = std::move(paths);
    s->step_ = t0;
    for (int i : chosen) {
      Agent a;
      a.id = scenario->tracks[i].id;
      a.type = model_type(scenario->tracks[i].type);
      a.controlled = true;
      a.entered_step = t0;
      a.state = step_state_from_object(scenario->tracks[i].states[now_frame]);
      a.kin = kinematic_state(a.state);
      s->agents_.push_back(a);
    }
    s->join_logged_agents();
    for (Light& l : s->lights_) l.state = log_light_state(*scenario, l.lane, now_frame);
    s->plan_rule_agents();
    return s;
  }

  // Log agents: the SDC's neighbours first (tracks to predict, then by distance), within the region of interest.
  const Vec2 centre = num_controlled > 0
                          ? Vec2{scenario->tracks[chosen[0]].states[now_frame].x, scenario->tracks[chosen[0]].states[now_frame].y}
                          : scenario_focus(*scenario);
  if (options.mode != SessionMode::full) {
    std::vector<std::pair<double, int>> rest;
    for (size_t i = 0; i < scenario->tracks.size(); ++i) {
      const Track& t = scenario->tracks[i];
      if (model_type(t.type) < 0 || !t.states[now_frame].valid) continue;
      if (std::find(chosen.begin(), chosen.end(), static_cast<int>(i)) != chosen.end()) continue;
      const double d = distance({t.states[now_frame].x, t.states[now_frame].y}, centre);
      if (d > options.roi_radius) continue;
      const bool predicted = std::any_of(scenario->tracks_to_predict.begin(), scenario->tracks_to_predict.end(),
                                         [&](const RequiredPrediction& r) { return r.track_index == static_cast<int>(i); });
      rest.push_back({predicted ? -1.0 : d, static_cast<int>(i)});
    }
    std::stable_sort(rest.begin(), rest.end());
    for (const auto& [d, i] : rest)
      if (static_cast<int>(chosen.size()) < options.max_agents) chosen.push_back(i);
  }

  // Each chosen agent joins at the start of its last unbroken run of valid steps up to t0.
  struct LogAgent {
    int track = 0;
    int first_step = 0;
    std::vector<StepState> steps;
    MotionTrack motion;
  };
  // Full mode starts its token sequence at the current step, where the model places the scene, as every training
  // sequence starts where its agents first appear. Steps of history before it would hold the controlled agents alone
  // (or nothing), a prefix no training sequence has: with it the model placed agents less like the log's
  // (val, K = 32, with session.cc's placement temperature: realism 0.571 -> 0.602; docs/model.md, "Full mode").
  const bool from_now = options.mode == SessionMode::full;
  std::vector<LogAgent> log;
  for (int i : chosen) {
    LogAgent la;
    la.track = i;
    la.steps = downsample_track(scenario->tracks[i]);
    // Tokens up to t0 only: the log's later steps are never replayed, and fitting them (a search over the motion
    // vocabulary per step) was 2.3 % of a busy server's time. Each token depends only on the steps before it.
    la.motion = tokenize_motion(std::span(la.steps).first(std::min(la.steps.size(), static_cast<size_t>(t0) + 1)));
    la.first_step = t0;
    while (!from_now && la.first_step > 0 && la.steps[la.first_step - 1].valid) --la.first_step;
    log.push_back(std::move(la));
  }
  std::vector<int> order(log.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return log[a].first_step < log[b].first_step; });

  // The history, teacher-forced; the model samples from the current step on.
  for (int step = from_now ? t0 : 0; step <= t0; ++step) {
    s->step_ = step;
    s->entered_.clear();
    for (int k : order) {
      const LogAgent& la = log[k];
      if (la.first_step != step) continue;
      Agent a;
      a.id = scenario->tracks[la.track].id;
      a.type = model_type(scenario->tracks[la.track].type);
      a.slot = s->allocate_slot();
      a.controlled = static_cast<size_t>(&la - log.data()) < num_controlled;
      a.entered_step = step;
      s->agents_.push_back(a);
    }
    for (Agent& a : s->agents_) {
      const LogAgent& la = *std::find_if(log.begin(), log.end(), [&](const LogAgent& l) { return scenario->tracks[l.track].id == a.id; });
      a.state = la.steps[step];
      a.kin = kinematic_state(a.state);
      a.last_motion = step == la.first_step ? kMotionStart : la.motion.tokens[step];  // START: its first step
    }
    for (Light& l : s->lights_) l.state = log_light_state(*scenario, l.lane, step * kFramesPerStep);
    s->trim_replay();
    const bool now = step == t0;
    const bool sample_new = now && options.mode == SessionMode::full;
    if (sample_new && by_count) s->quota_.assign(options.agent_counts.begin(), options.agent_counts.end());
    const int force_new = now && options.mode == SessionMode::densify
                              ? std::max(0, options.densify_target - static_cast<int>(s->agents_.size()))
                              : 0;
    if (auto st = s->decode_step(now, sample_new, force_new, {}, nullptr); !st.ok()) return st;
    s->quota_.clear();
  }
  return s;
}

}  // namespace ss
