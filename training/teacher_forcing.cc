#include "training/teacher_forcing.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "engine/map/focus.h"
#include "engine/map/spatial_index.h"
#include "engine/model/attention.h"
#include "engine/model/key_select.h"
#include "engine/model/model.h"
#include "engine/base/rng.h"
#include "engine/sim/token_builders.h"
#include "engine/tokens/fidelity.h"
#include "engine/tokens/motion.h"

namespace ss {
namespace {

// A log agent in the sequence: from its first step in the region to the end of that run.
struct SeqAgent {
  int track = 0;
  int first = 0, last = 0;          // steps, inclusive
  std::vector<StepState> log;       // per step: the log's state (invalid outside first..last)
  std::vector<StepState> states;    // per step: the tokens' input (the motion tokens' reconstruction, the log's box)
  std::vector<int> motion;          // per step: the token that brought it there (START at `first`)
  std::vector<int> target;          // per step: the motion target read at that step (the next step's token)
  int rank = 0;                     // 0 SDC, 1 a track to predict, 2 the others
  double distance = 0;              // from the region's centre at its first step
};

void add_keys(KeyLists& lists, const std::vector<int>& keys, const Anchor& q, auto key_anchor) {
  for (int j : keys) {
    lists.keys.push_back(j);
    const RelationFeatures f = relation_features(q, key_anchor(j));
    lists.features.insert(lists.features.end(), f.begin(), f.end());
  }
}

void close_query(KeyLists& lists) { lists.offsets.push_back(static_cast<int>(lists.keys.size())); }

}  // namespace

void append_decoder_keys(std::span<const DecoderToken> cached, std::span<const DecoderToken> fresh,
                         std::span<const MapSegment> segments, const SegmentIndex& index, const ModelConfig& config,
                         KeyLists& self, KeyLists& cross) {
  const NeighbourLimit limit{config.knn_k, config.knn_radius, config.knn_always};
  const int c = static_cast<int>(cached.size());
  auto anchor_of = [&](int j) {
    const DecoderToken& t = j < c ? cached[j] : fresh[j - c];
    return Anchor(t.has_pose, t.pose, t.step);
  };
  SelfKeySelector selector(cached, fresh, config.window_steps, limit);
  SelfKeys keys;
  for (size_t i = 0; i < fresh.size(); ++i) {
    const DecoderToken& q = fresh[i];
    selector.select(static_cast<int>(i), keys);
    const Anchor qa = anchor_of(c + static_cast<int>(i));
    add_keys(self, keys.posed, qa, anchor_of);
    add_keys(self, keys.unposed, qa, anchor_of);
    close_query(self);
    if (q.has_pose)  // map tokens carry the query's step: the step difference is 0
      add_keys(cross, map_keys_near(segments, index, {q.pose.x, q.pose.y}, limit), Anchor(true, q.pose, 0),
               [&](int j) { return Anchor(true, segments[j].pose, 0); });
    close_query(cross);
  }
}

void fill_map_inputs(TeacherForcedExample& ex, const ModelConfig& config) {
  const SegmentIndex index(ex.segments);
  const NeighbourLimit limit{config.knn_k, config.knn_radius, config.knn_always};
  ex.point_features.clear();
  ex.point_segment.clear();
  ex.map_keys = {};
  for (size_t i = 0; i < ex.segments.size(); ++i) {
    const SegmentFeatures f = segment_point_features(ex.segments[i]);
    const int n = std::min(ex.segments[i].num_vectors(), kMaxVectorsPerSegment);
    ex.point_features.insert(ex.point_features.end(), f.begin(), f.begin() + n * kPointFeatureDim);
    ex.point_segment.insert(ex.point_segment.end(), n, static_cast<int>(i));
    const Pose& p = ex.segments[i].pose;
    add_keys(ex.map_keys, map_keys_near(ex.segments, index, {p.x, p.y}, limit), Anchor(true, p, 0),
             [&](int j) { return Anchor(true, ex.segments[j].pose, 0); });
    close_query(ex.map_keys);
  }
}

namespace {

// The closed-loop choice of CAT-K: among the `top_k` most probable tokens of `logits`, the one whose next box is
// nearest (Average Corner Error) the log's next box; ties go to the more probable.
int closest_among_top_k(std::span<const float> logits, int top_k, const KinematicState& from, const StepState& next) {
  std::vector<int> order(logits.size());
  std::iota(order.begin(), order.end(), 0);
  const int k = std::min<int>(top_k, static_cast<int>(order.size()));
  std::partial_sort(order.begin(), order.begin() + k, order.end(),
                    [&](int a, int b) { return logits[a] != logits[b] ? logits[a] > logits[b] : a < b; });
  const Box target{{next.x, next.y, next.heading}, next.length, next.width};
  int best = order[0];
  double best_ace = std::numeric_limits<double>::infinity();
  for (int i = 0; i < k; ++i) {
    const KinematicState s = apply_motion_token(from, order[i]);
    const double ace = average_corner_error({{s.x, s.y, s.heading}, next.length, next.width}, target);
    if (ace < best_ace) {
      best_ace = ace;
      best = order[i];
    }
  }
  return best;
}

StepState with_kinematics(StepState s, const KinematicState& k) {
  s.x = k.x;
  s.y = k.y;
  s.heading = k.heading;
  s.vx = k.speed * std::cos(k.heading);
  s.vy = k.speed * std::sin(k.heading);
  return s;
}

// The example of the log (policy null) or of a CAT-K rollout of `policy` (closed_loop_example).
absl::StatusOr<TeacherForcedExample> build_example(const Scenario& scenario, const ModelConfig& config,
                                                   const TeacherForcingOptions& options, const Model* policy, int top_k) {
  if (options.phase < 0 || options.phase >= kFramesPerStep)
    return absl::InvalidArgumentError(absl::StrCat("teacher forcing: phase ", options.phase, " is outside 0..4"));
  if (options.max_agents < 1 || options.max_agents > config.agent_slots)
    return absl::InvalidArgumentError(absl::StrCat("teacher forcing: max_agents ", options.max_agents, " is outside 1..",
                                                   config.agent_slots));
  const int frames = scenario.num_frames() - options.phase;
  const int steps = frames > 0 ? num_model_steps(frames) : 0;
  if (steps < 2)
    return absl::InvalidArgumentError(absl::StrCat("teacher forcing: scenario ", scenario.id, " has ", scenario.num_frames(),
                                                   " frames, fewer than two steps at phase ", options.phase));
  auto frame_of = [&](int step) { return options.phase + step * kFramesPerStep; };

  TeacherForcedExample ex;
  ex.scenario_id = scenario.id;
  ex.phase = options.phase;
  ex.steps = steps;
  const int max_segments = options.max_map_segments > 0 ? std::min(options.max_map_segments, config.max_map_segments)
                                                         : config.max_map_segments;
  ex.segments = nearest_segments(segment_map(scenario), scenario_focus(scenario), max_segments);
  if (ex.segments.empty())
    return absl::FailedPreconditionError(absl::StrCat("teacher forcing: scenario ", scenario.id, " has no map segments"));
  const SegmentIndex index(ex.segments);
  fill_map_inputs(ex, config);

  // The region's centre at each step: the SDC while the log has it, else the scenario's focus.
  const Vec2 focus = scenario_focus(scenario);
  const Track* sdc = scenario.sdc_track_index >= 0 && scenario.sdc_track_index < static_cast<int>(scenario.tracks.size())
                         ? &scenario.tracks[scenario.sdc_track_index]
                         : nullptr;
  std::vector<Vec2> centre(steps, focus);
  if (sdc)
    for (int t = 0; t < steps; ++t)
      if (const ObjectState& s = sdc->states[frame_of(t)]; s.valid) centre[t] = {s.x, s.y};

  // Agents: each track's first run of steps valid and inside the region.
  std::vector<SeqAgent> agents;
  for (size_t i = 0; i < scenario.tracks.size(); ++i) {
    const Track& track = scenario.tracks[i];
    if (model_type(track.type) < 0) continue;
    std::vector<StepState> log(steps);
    for (int t = 0; t < steps; ++t) log[t] = step_state_from_object(track.states[frame_of(t)]);
    int first = 0;
    auto inside = [&](int t) { return log[t].valid && distance({log[t].x, log[t].y}, centre[t]) <= options.roi_radius; };
    while (first < steps && !inside(first)) ++first;
    if (first == steps) continue;
    int last = first;
    while (last + 1 < steps && inside(last + 1)) ++last;
    SeqAgent a;
    a.track = static_cast<int>(i);
    a.first = first;
    a.last = last;
    a.log.assign(steps, StepState{});
    for (int t = first; t <= last; ++t) a.log[t] = log[t];
    const bool predicted = std::any_of(scenario.tracks_to_predict.begin(), scenario.tracks_to_predict.end(),
                                       [&](const RequiredPrediction& r) { return r.track_index == static_cast<int>(i); });
    a.rank = &track == sdc ? 0 : predicted ? 1 : 2;
    a.distance = distance({log[first].x, log[first].y}, centre[first]);
    agents.push_back(std::move(a));
  }
  std::stable_sort(agents.begin(), agents.end(), [](const SeqAgent& a, const SeqAgent& b) {
    return a.rank != b.rank ? a.rank < b.rank : a.distance < b.distance;
  });
  // Steps where an agent beyond the cap is inside the region: the scene goes on after the last agent kept, so
  // that step's end of agents is not the log's answer and has no target (an end there would teach the model that
  // scenes stop at the cap).
  std::vector<bool> capped(steps, false);
  for (size_t k = options.max_agents; k < agents.size(); ++k)
    for (int t = agents[k].first; t <= agents[k].last; ++t) capped[t] = true;
  if (static_cast<int>(agents.size()) > options.max_agents) agents.resize(options.max_agents);
  // Motion tokens for the agents kept (the search over 1089 controls is the costly part), rolled forward on their
  // reconstruction; the tokens' inputs are the reconstructed states, as a rollout's are. A closed-loop example
  // knows only each agent's first state here; the policy moves it step by step below.
  for (SeqAgent& a : agents) {
    a.states = a.log;
    a.target.assign(steps, kNoTarget);
    if (policy) {
      a.motion.assign(steps, -1);
      a.motion[a.first] = kMotionStart;
      a.states[a.first] = with_kinematics(a.log[a.first], kinematic_state(a.log[a.first]));
      continue;
    }
    const MotionTrack motion = tokenize_motion(a.log);
    a.motion = motion.tokens;
    for (int t = a.first; t <= a.last; ++t) {
      a.states[t] = with_kinematics(a.log[t], motion.reconstructed[t]);
      if (t < a.last && a.motion[t + 1] >= 0 && a.motion[t + 1] < kMotionVocab) a.target[t] = a.motion[t + 1];
    }
  }
  // In order of entry, as a session's agent list.
  std::stable_sort(agents.begin(), agents.end(), [](const SeqAgent& a, const SeqAgent& b) { return a.first < b.first; });
  ex.agents = static_cast<int>(agents.size());
  std::vector<int> slots(config.agent_slots);
  std::iota(slots.begin(), slots.end(), 0);
  if (options.slot_seed != 0) {
    Rng rng(options.slot_seed);
    for (int i = config.agent_slots - 1; i > 0; --i) std::swap(slots[i], slots[rng.next() % (i + 1)]);
  }

  const std::vector<TokenLight> lights =
      scenario_lights(scenario, scenario.current_time_index, ex.segments, index, config.light_slots);

  // The sequence, step by step: lights, the agent-state group, motion.
  auto add = [&](const DecoderToken& t) {
    ex.tokens.push_back(t);
    ex.tokens.back().seq = static_cast<int64_t>(ex.tokens.size()) - 1;
    ex.light_target.push_back(kNoTarget);
    ex.motion_target.push_back(kNoTarget);
    ex.type_target.push_back(kNoTarget);
    ex.segment_target.push_back(kNoTarget);
    ex.end_target.push_back(kNoTarget);
    std::array<int, kRsFields> none;
    none.fill(kNoTarget);
    ex.state_target.push_back(none);
    return static_cast<int>(ex.tokens.size()) - 1;
  };
  std::shared_ptr<const MapContext> map;
  KvCache cache;
  if (policy) {
    auto encoded = policy->encode_map(ex.segments);
    if (!encoded.ok()) return encoded.status();
    map = *encoded;
    cache = policy->new_cache();
  }
  for (int t = 0; t < steps; ++t) {
    const size_t step_begin = ex.tokens.size();
    std::vector<int> motion_rows;  // the step's motion tokens, as indices from step_begin
    std::vector<SeqAgent*> moving;  // their agents
    for (size_t k = 0; k < lights.size(); ++k) {
      const int i = add(light_token(t, static_cast<int>(k), lights[k], log_light_state(scenario, lights[k].lane, frame_of(t))));
      if (t + 1 < steps) ex.light_target[i] = static_cast<int>(log_light_state(scenario, lights[k].lane, frame_of(t + 1)));
    }
    std::vector<TokenAgent> alive;
    for (size_t k = 0; k < agents.size(); ++k) {
      const SeqAgent& a = agents[k];
      if (t < a.first || t > a.last) continue;
      alive.push_back({scenario.tracks[a.track].id, slots[k], model_type(scenario.tracks[a.track].type), a.states[t],
                       a.motion[t]});
    }
    const int end = capped[t] ? kNoTarget : 1;
    ex.end_target[add(sos_token(t))] = alive.empty() ? end : 0;
    for (size_t o = 0; o < alive.size(); ++o) {
      std::vector<DecoderToken> group;
      const int seg = anchor_segment(index, alive[o].state);
      agent_group_tokens(t, alive[o], static_cast<int>(o), seg, ex.segments[seg], group);
      ex.type_target[add(group[0])] = alive[o].type;
      ex.segment_target[add(group[1])] = seg;
      const StateBins bins = relative_state_bins(alive[o].state, ex.segments[seg].pose);
      std::copy(bins.begin(), bins.end(), ex.state_target[add(group[2])].begin());
      ex.end_target[add(group[3])] = o + 1 < alive.size() ? 0 : end;
    }
    add(eos_token(t));
    for (size_t k = 0, o = 0; k < agents.size(); ++k) {
      SeqAgent& a = agents[k];
      if (t < a.first || t > a.last) continue;
      const int i = add(agent_motion_token(t, alive[o++]));
      motion_rows.push_back(i - static_cast<int>(step_begin));
      moving.push_back(&a);
    }
    if (policy && t + 1 < steps) {
      // The step through the policy, as a session runs it (the cache keeps what the window needs); each agent
      // moves by its closest-among-top-k token, and its target is re-tokenised from where it is to the log's next
      // pose, so the model learns to recover from its own drift.
      cache.evict_before(t - config.window_steps + 1);
      std::vector<DecoderToken> fresh(ex.tokens.begin() + step_begin, ex.tokens.end());
      const Mat logits = policy->motion_logits(policy->decode(*map, cache, fresh, motion_rows));
      for (size_t r = 0; r < moving.size(); ++r) {
        SeqAgent& a = *moving[r];
        if (t + 1 > a.last) continue;
        const KinematicState from = kinematic_state(a.states[t]);
        const StepState& next = a.log[t + 1];
        const int chosen = closest_among_top_k({logits.row(r).data(), static_cast<size_t>(logits.cols())}, top_k, from, next);
        a.motion[t + 1] = chosen;
        a.states[t + 1] = with_kinematics(next, apply_motion_token(from, chosen));
        a.target[t] = fit_motion_token(from, {next.x, next.y, next.heading}, next.length, next.width).token;
      }
    }
    for (size_t r = 0; r < moving.size(); ++r) ex.motion_target[step_begin + motion_rows[r]] = moving[r]->target[t];
  }

  // Keys: the decoder's own selection over the whole sequence (a fresh cache).
  append_decoder_keys({}, ex.tokens, ex.segments, index, config, ex.self_keys, ex.cross_keys);
  return ex;
}

}  // namespace

absl::StatusOr<TeacherForcedExample> teacher_forced_example(const Scenario& scenario, const ModelConfig& config,
                                                            const TeacherForcingOptions& options) {
  return build_example(scenario, config, options, nullptr, 0);
}

absl::StatusOr<TeacherForcedExample> closed_loop_example(const Scenario& scenario, const Model& policy,
                                                         const TeacherForcingOptions& options, int top_k) {
  if (top_k < 1) return absl::InvalidArgumentError(absl::StrCat("closed loop: top_k ", top_k, " must be at least 1"));
  return build_example(scenario, policy.config(), options, &policy, top_k);
}

}  // namespace ss
