#include "offline/eval/scenario_gen.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "engine/base/rng.h"
#include "offline/eval/baselines.h"
#include "offline/eval/evaluate.h"
#include "offline/eval/model_rollout.h"
#include "engine/map/focus.h"
#include "engine/sim/rollout_export.h"
#include "engine/tokens/fidelity.h"

namespace ss {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kPlacementDraws = 50;       // the placement baseline's redraws of an overlapping box
constexpr double kSidewalkOffset = 1.5;   // metres beyond a road edge, on its off-road side

bool is_sdc(const Scenario& s, int track) { return track == s.sdc_track_index; }
bool has_sdc(const Scenario& s) {
  return s.sdc_track_index >= 0 && s.tracks[s.sdc_track_index].states[s.current_time_index].valid;
}

// Every frame's box of a track at constant velocity (vx, vy) through (x, y) at frame `now`, heading held.
std::vector<BoxState> constant_velocity_states(int frames, int now, const BoxState& at_now, double vx, double vy) {
  std::vector<BoxState> out(frames, at_now);
  for (int f = 0; f < frames; ++f) {
    const double dt = (f - now) * kEvalFrameSeconds;
    out[f].x = at_now.x + vx * dt;
    out[f].y = at_now.y + vy * dt;
    out[f].valid = true;
  }
  return out;
}

// The overlapping pairs of boxes among the scene's objects at frame f.
int overlapping_pairs(const JointScene& scene, int f) {
  int n = 0;
  const auto box = [&](const BoxState& b) { return Box{{b.x, b.y, b.heading}, b.length, b.width}; };
  for (size_t i = 0; i < scene.objects.size(); ++i)
    for (size_t j = i + 1; j < scene.objects.size(); ++j) {
      const BoxState& a = scene.objects[i].states[f];
      const BoxState& b = scene.objects[j].states[f];
      if (a.valid && b.valid && boxes_overlap(box(a), box(b))) ++n;
    }
  return n;
}

// The scene's objects skeleton: the sim agents' ids and log types, no states yet.
JointScene empty_scene(const Scenario& s, const std::vector<int>& tracks) {
  JointScene scene;
  for (int t : tracks) scene.objects.push_back({s.tracks[t].id, s.tracks[t].type, {}});
  return scene;
}

// The SDC's states: its log up to the current frame (the challenge's input), then `future` (already 10 Hz, frame
// now + j at index j), else constant velocity.
std::vector<BoxState> sdc_states(const Scenario& s, const std::vector<StepState>* future) {
  const Track& t = s.tracks[s.sdc_track_index];
  const int now = s.current_time_index, frames = s.num_frames();
  std::vector<BoxState> st(frames);
  for (int f = 0; f <= now; ++f) st[f] = box_state(t.states[f]);
  const ObjectState& o = t.states[now];
  // A frame of history the log lacks: moved back at the current velocity (a submission has every frame).
  for (int f = now - 1; f >= 0; --f)
    if (!st[f].valid) {
      st[f] = st[f + 1];
      st[f].x -= o.vx * kEvalFrameSeconds, st[f].y -= o.vy * kEvalFrameSeconds;
      st[f].valid = true;
    }
  int last = now;
  if (future)
    for (int f = now + 1; f < frames && f - now < static_cast<int>(future->size()); ++f) {
      const StepState& p = (*future)[f - now];
      if (!p.valid) break;
      st[f] = {p.x, p.y, o.z, p.heading, o.length, o.width, o.height, true};
      last = f;
    }
  double vx = o.vx, vy = o.vy;
  if (future && last > now) vx = (*future)[last - now].vx, vy = (*future)[last - now].vy;
  extend_constant_velocity(st, last, vx, vy);
  return st;
}

// The placement baseline's rule: random lane points for vehicles and cyclists, sidewalk points for pedestrians, the
// box and speed of a random log agent of the type, redrawn where the box would overlap one already placed.
class Placer {
 public:
  Placer(const Scenario& s, double radius, uint64_t seed) : s_(s), rng_(seed) {
    const int now = s.current_time_index;
    centre_ = scenario_focus(s);
    if (s.sdc_track_index >= 0 && s.tracks[s.sdc_track_index].states[now].valid)
      centre_ = {s.tracks[s.sdc_track_index].states[now].x, s.tracks[s.sdc_track_index].states[now].y};
    // Candidate poses: lane centres (with their direction) for vehicles and cyclists; beside road edges (their
    // off-road side is the right of their direction, metrics-spec.md A5) and crosswalk corners for pedestrians.
    for (const MapFeature& m : s.map_features) {
      const auto& p = m.points;
      for (size_t i = 0; i + 1 < p.size(); ++i) {
        const double dx = p[i + 1].x - p[i].x, dy = p[i + 1].y - p[i].y, len = std::hypot(dx, dy);
        if (len < 1e-6) continue;
        const double h = std::atan2(dy, dx);
        if (m.kind == MapFeatureKind::lane) lanes_.push_back({p[i].x, p[i].y, h});
        if (m.kind == MapFeatureKind::road_edge)
          walks_.push_back({p[i].x + kSidewalkOffset * dy / len, p[i].y - kSidewalkOffset * dx / len, h});
      }
      if (m.kind == MapFeatureKind::crosswalk)
        for (const MapPoint& q : p) walks_.push_back({q.x, q.y, 0.0});
    }
    for (auto* v : {&lanes_, &walks_})
      std::erase_if(*v, [&](const Pose& q) { return distance({q.x, q.y}, centre_) > radius; });
    if (walks_.empty()) walks_ = lanes_;
    // The log's agents of each type at the current frame (all but the SDC): the boxes and speeds drawn.
    for (int t : sim_agent_tracks(s))
      if (!is_sdc(s, t)) log_of_[model_type(s.tracks[t].type)].push_back(&s.tracks[t].states[now]);
  }

  // A box of `type` (which the log has at the current frame) clear of `placed` if 50 draws find one; its velocity.
  BoxState place(int type, const std::vector<BoxState>& placed, double* vx, double* vy) {
    const auto box = [](const BoxState& b) { return Box{{b.x, b.y, b.heading}, b.length, b.width}; };
    const std::vector<Pose>& points = type == 1 ? walks_ : lanes_;
    BoxState b;
    double speed = 0;
    for (int draw = 0; draw < kPlacementDraws; ++draw) {
      const ObjectState& like = *log_of_[type][rng_.integer(0, static_cast<int64_t>(log_of_[type].size()) - 1)];
      Pose q = points.empty() ? Pose{centre_.x, centre_.y, 0.0}
                              : points[rng_.integer(0, static_cast<int64_t>(points.size()) - 1)];
      if (type == 1) q.heading = rng_.uniform(-M_PI, M_PI);  // pedestrians walk either way
      const double z = ground_z(s_, q.x, q.y);
      b = {q.x, q.y, (std::isfinite(z) ? z : 0.0) + like.height / 2, q.heading, like.length, like.width, like.height,
           true};
      speed = std::hypot(like.vx, like.vy);
      if (std::none_of(placed.begin(), placed.end(), [&](const BoxState& o) { return boxes_overlap(box(o), box(b)); }))
        break;
    }
    *vx = speed * std::cos(b.heading), *vy = speed * std::sin(b.heading);
    return b;
  }

 private:
  const Scenario& s_;
  Rng rng_;
  Vec2 centre_;
  std::vector<Pose> lanes_, walks_;
  std::array<std::vector<const ObjectState*>, 3> log_of_;
};

}  // namespace

std::array<int, 3> model_request(std::array<int, 3> requested, int slots) {
  // Vehicles first: in a crowded scene they are the many.
  for (int excess = requested[0] + requested[1] + requested[2] - std::max(0, slots); excess > 0; --excess)
    --*std::max_element(requested.begin(), requested.end());
  return requested;
}

std::array<int, 3> scenario_gen_counts(const Scenario& s) {
  std::array<int, 3> c{};
  for (int t : sim_agent_tracks(s)) {
    const int m = model_type(s.tracks[t].type);
    if (m >= 0 && !is_sdc(s, t)) ++c[m];
  }
  return c;
}

std::string scenario_gen_problem(const Scenario& s) {
  const std::vector<int> tracks = sim_agent_tracks(s);
  if (tracks.empty()) return absl::StrCat("no agent is valid at the current frame ", s.current_time_index);
  for (int t : tracks)
    if (model_type(s.tracks[t].type) < 0)
      return absl::StrCat("sim agent ", s.tracks[t].id, " is of type ", object_type_name(s.tracks[t].type),
                          ", which the model does not generate");
  if (s.current_time_index % kFramesPerStep != 0)
    return absl::StrCat("current frame ", s.current_time_index, " is not a 2 Hz step");
  return "";
}

absl::StatusOr<std::array<int, 3>> parse_agent_counts(const std::string& text) {
  const std::vector<std::string> parts = absl::StrSplit(text, ',');
  if (parts.size() != 3)
    return absl::InvalidArgumentError(absl::StrCat("'", text, "' is not V,P,C (vehicles, pedestrians, cyclists)"));
  std::array<int, 3> c{};
  for (int k = 0; k < 3; ++k)
    if (!absl::SimpleAtoi(parts[k], &c[k]) || c[k] < 0 || c[k] > 1024)
      return absl::InvalidArgumentError(absl::StrCat("'", parts[k], "' in '", text, "' is not a count in 0..1024"));
  return c;
}

bool scenario_gen_aggregated(RealismFeature f) { return f != kTrafficLightViolation; }

RealismScores score_scenario_gen(const SceneFeatures& log, std::span<const SceneFeatures> sims,
                                 std::span<const ObjectType> types) {
  RealismScores r;
  const auto& config = wosac_2025_config();
  const size_t objects = types.size();
  std::array<std::vector<std::vector<uint8_t>>, kNumRealismFeatures> masks;
  for (int f = 0; f < kNumRealismFeatures; ++f)
    for (size_t i = 0; i < objects; ++i)
      masks[f].push_back(feature_mask(static_cast<RealismFeature>(f), log.valid[i], types[i]));
  // "Any in the masked frames": the indications aggregate over time before the objects are pooled.
  auto indication = [&](const SceneFeatures& s, int f, size_t i) -> uint8_t {
    const auto& v = s.values[f][i];
    for (size_t t = 0; t < v.size(); ++t)
      if (masks[f][i][t] && v[t] > 0.5) return 1;
    return 0;
  };
  for (int f = 0; f < kNumRealismFeatures; ++f) {
    const RealismFeature feature = static_cast<RealismFeature>(f);
    double sum = 0;
    size_t count = 0;
    if (config[f].bernoulli) {
      const double a = config[f].histogram.pseudo_count;
      if (scenario_gen_aggregated(feature)) {
        std::vector<uint8_t> pooled;  // every rollout's every object
        for (const SceneFeatures& s : sims)
          for (size_t i = 0; i < objects; ++i) pooled.push_back(indication(s, f, i));
        for (size_t i = 0; i < objects; ++i) sum += bernoulli_log_likelihood(a, indication(log, f, i), pooled), ++count;
      } else {
        for (size_t i = 0; i < objects; ++i) {
          std::vector<uint8_t> sim;
          for (const SceneFeatures& s : sims) sim.push_back(indication(s, f, i));
          sum += bernoulli_log_likelihood(a, indication(log, f, i), sim);
          ++count;
        }
      }
    } else {
      // aggregate_objects and independent_timesteps: one histogram of every rollout's, object's and frame's value.
      std::vector<double> pooled;
      for (const SceneFeatures& s : sims)
        for (size_t i = 0; i < objects; ++i) pooled.insert(pooled.end(), s.values[f][i].begin(), s.values[f][i].end());
      const HistogramConfig& h = config[f].histogram;
      const std::vector<double> p = histogram_probabilities(h, pooled);
      for (size_t i = 0; i < objects; ++i)
        for (size_t t = 0; t < masks[f][i].size(); ++t)
          if (masks[f][i][t]) {
            const double v = log.values[f][i][t];
            sum += std::log(p[std::isnan(v) ? 0 : histogram_bin(h, v)]);
            ++count;
          }
    }
    r.likelihood[f] = count ? std::exp(sum / count) : kNaN;
  }
  r.meta = 0;
  for (int f = 0; f < kNumRealismFeatures; ++f) r.meta += config[f].weight * r.likelihood[f];
  r.kinematic = bucket_score(RealismBucket::kinematic, r.likelihood);
  r.interactive = bucket_score(RealismBucket::interactive, r.likelihood);
  r.map = bucket_score(RealismBucket::map, r.likelihood);
  double collisions = 0, offroads = 0;
  for (const SceneFeatures& s : sims)
    for (size_t i = 0; i < objects; ++i) collisions += indication(s, kCollision, i), offroads += indication(s, kOffroad, i);
  const double pairs = static_cast<double>(sims.size() * objects);
  r.collision_rate = pairs ? collisions / pairs : kNaN;
  r.offroad_rate = pairs ? offroads / pairs : kNaN;
  r.ade = r.min_ade = kNaN;
  r.objects = static_cast<int>(objects);
  return r;
}

absl::StatusOr<GeneratedScene> generated_scene(const Scenario& s, const std::vector<StepResult>& steps,
                                               const std::array<int, 3>& requested, double radius, uint64_t seed,
                                               ScenarioGenHistory history) {
  const int now = s.current_time_index, frames = s.num_frames();
  const std::vector<int> tracks = sim_agent_tracks(s);
  GeneratedScene out;
  out.scene = empty_scene(s, tracks);
  if (steps.empty()) return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, ": an empty rollout"));
  std::vector<RolloutAgent> agents = rollout_agents(steps);
  const int64_t sdc_id = s.sdc_track_index >= 0 ? s.tracks[s.sdc_track_index].id : -1;
  // The generated agents of each type, in the order the model placed them.
  std::array<std::vector<const RolloutAgent*>, 3> by_type;
  const RolloutAgent* sdc = nullptr;
  for (const RolloutAgent& a : agents) {
    if (a.id == sdc_id) {
      sdc = &a;
      continue;
    }
    if (a.frames.empty() || !a.frames[0].valid) continue;  // joined after the first step (not by count)
    by_type[a.type].push_back(&a);
  }
  std::array<int, 3> got{};
  for (int k = 0; k < 3; ++k) got[k] = static_cast<int>(by_type[k].size());
  if (got != requested)
    return absl::InternalError(absl::StrCat("scenario ", s.id, ": the rollout placed ", got[0], ",", got[1], ",", got[2],
                                            " agents, not the requested ", requested[0], ",", requested[1], ",",
                                            requested[2]));
  std::array<size_t, 3> next{};
  std::vector<size_t> unplaced;  // tracks beyond the request (a scenario with more agents than the model's slots)
  std::vector<BoxState> placed;
  for (size_t k = 0; k < tracks.size(); ++k) {
    std::vector<BoxState>& st = out.scene.objects[k].states;
    if (is_sdc(s, tracks[k])) {
      st = sdc_states(s, sdc ? &sdc->frames : nullptr);
      placed.push_back(st[now]);
      continue;
    }
    const int type = model_type(s.tracks[tracks[k]].type);
    if (next[type] == by_type[type].size()) {
      unplaced.push_back(k);
      continue;
    }
    const RolloutAgent& a = *by_type[type][next[type]++];
    const StepState& g = a.frames[0];
    const double z = ground_z(s, g.x, g.y);
    const BoxState at_now{g.x, g.y, (std::isfinite(z) ? z : 0.0) + g.height / 2, g.heading, g.length, g.width, g.height,
                          true};
    st = constant_velocity_states(frames, now, at_now, g.vx, g.vy);  // the history (and a fallback future)
    int last = now;
    for (int f = now + 1; f < frames && f - now < static_cast<int>(a.frames.size()); ++f) {
      const StepState& p = a.frames[f - now];
      if (!p.valid) break;
      st[f] = {p.x, p.y, at_now.z, p.heading, g.length, g.width, g.height, true};
      last = f;
    }
    if (last > now) extend_constant_velocity(st, last, a.frames[last - now].vx, a.frames[last - now].vy);
    placed.push_back(at_now);
    ++out.placed[type];
  }
  if (!unplaced.empty()) {
    Placer placer(s, radius, seed);
    for (size_t k : unplaced) {
      const int type = model_type(s.tracks[tracks[k]].type);
      double vx = 0, vy = 0;
      const BoxState b = placer.place(type, placed, &vx, &vy);
      out.scene.objects[k].states = constant_velocity_states(frames, now, b, vx, vy);
      placed.push_back(b);
      ++out.placed[type];
      ++out.filled;
    }
  }
  if (history == ScenarioGenHistory::clear) {
    std::vector<size_t> moved;
    for (size_t k = 0; k < tracks.size(); ++k)
      if (!is_sdc(s, tracks[k])) moved.push_back(k);
    clear_history(out.scene, now, moved);
  }
  out.overlapping_pairs = overlapping_pairs(out.scene, now);
  return out;
}

GeneratedScene placement_scene(const Scenario& s, double radius, uint64_t seed) {
  const int now = s.current_time_index, frames = s.num_frames();
  const std::vector<int> tracks = sim_agent_tracks(s);
  Placer placer(s, radius, seed);
  GeneratedScene out;
  out.scene = empty_scene(s, tracks);
  std::vector<BoxState> placed;
  for (size_t k = 0; k < tracks.size(); ++k)
    if (is_sdc(s, tracks[k])) {
      out.scene.objects[k].states = sdc_states(s, nullptr);
      placed.push_back(out.scene.objects[k].states[now]);
    }
  for (size_t k = 0; k < tracks.size(); ++k) {
    if (is_sdc(s, tracks[k])) continue;
    const int type = model_type(s.tracks[tracks[k]].type);
    double vx = 0, vy = 0;
    const BoxState b = placer.place(type, placed, &vx, &vy);
    out.scene.objects[k].states = constant_velocity_states(frames, now, b, vx, vy);
    placed.push_back(b);
    ++out.placed[type];
  }
  out.overlapping_pairs = overlapping_pairs(out.scene, now);
  return out;
}

GeneratedScene log_oracle_scene(const Scenario& s) {
  const int now = s.current_time_index;
  const std::vector<int> tracks = sim_agent_tracks(s);
  GeneratedScene out;
  out.scene = scenario_gen_log_scene(s);
  for (size_t k = 0; k < tracks.size(); ++k) {
    const Track& t = s.tracks[tracks[k]];
    std::vector<BoxState>& st = out.scene.objects[k].states;
    // Forward from each valid frame at its velocity, then the frames before the first valid one backward.
    int first = -1, last_valid = -1;
    for (size_t f = 0; f < st.size(); ++f) {
      if (t.states[f].valid) {
        if (first < 0) first = static_cast<int>(f);
        last_valid = static_cast<int>(f);
        continue;
      }
      if (first < 0) continue;
      st[f] = st[f - 1];
      st[f].x += t.states[last_valid].vx * kEvalFrameSeconds, st[f].y += t.states[last_valid].vy * kEvalFrameSeconds;
      st[f].valid = true;
    }
    for (int f = first - 1; f >= 0; --f) {
      st[f] = st[f + 1];
      st[f].x -= t.states[first].vx * kEvalFrameSeconds, st[f].y -= t.states[first].vy * kEvalFrameSeconds;
      st[f].valid = true;
    }
    const int m = model_type(t.type);
    if (is_sdc(s, tracks[k]) || m < 0) continue;
    ++out.placed[m];
  }
  out.overlapping_pairs = overlapping_pairs(out.scene, now);
  return out;
}

std::vector<InitialAgent> initial_agents(const Scenario& s, const JointScene& scene) {
  const int now = s.current_time_index;
  const std::vector<int> tracks = sim_agent_tracks(s);
  std::vector<InitialAgent> out;
  for (size_t k = 0; k < tracks.size() && k < scene.objects.size(); ++k) {
    if (is_sdc(s, tracks[k])) continue;
    const SceneObject& o = scene.objects[k];
    const BoxState& b = o.states[now];
    const BoxState& before = o.states[now > 0 ? now - 1 : now];
    const double dt = now > 0 ? kEvalFrameSeconds : 1.0;
    out.push_back({b.x, b.y, b.heading, b.length, b.width, (b.x - before.x) / dt, (b.y - before.y) / dt, o.type});
  }
  return out;
}

void clear_history(JointScene& scene, int now, const std::vector<size_t>& moved) {
  const auto box = [](const BoxState& b) { return Box{{b.x, b.y, b.heading}, b.length, b.width}; };
  const auto overlap = [&](const BoxState& a, const BoxState& b) {
    return std::abs(a.x - b.x) + std::abs(a.y - b.y) < a.length + b.length + a.width + b.width &&
           boxes_overlap(box(a), box(b));
  };
  std::vector<bool> is_moved(scene.objects.size(), false);
  for (size_t k : moved) is_moved[k] = true;
  std::vector<bool> held(scene.objects.size(), false);  // standing from the frame after back
  for (int f = now - 1; f >= 0; --f) {
    std::vector<bool> holding(scene.objects.size(), false);  // holds at this frame
    for (size_t k : moved)
      if (held[k]) scene.objects[k].states[f] = scene.objects[k].states[f + 1], holding[k] = true;
    const auto clear_of_settled = [&](const BoxState& c) {
      for (size_t o = 0; o < scene.objects.size(); ++o)
        if (!is_moved[o] && scene.objects[o].states[f].valid && overlap(scene.objects[o].states[f], c)) return false;
      return true;
    };
    // Every object's frame at once, so the order of `moved` does not decide who gives way: an agent whose step back
    // overlaps any box of this frame (settled, held or stepping) holds instead, until nothing changes. Holding only
    // ever replaces stepping, so this ends; two held boxes were clear of each other at the frame after.
    for (bool changed = true; changed;) {
      changed = false;
      for (size_t k : moved) {
        if (holding[k]) continue;
        const BoxState& b = scene.objects[k].states[f];
        bool clear = true;
        for (size_t o = 0; o < scene.objects.size() && clear; ++o)
          clear = o == k || !scene.objects[o].states[f].valid || !overlap(scene.objects[o].states[f], b);
        const BoxState& after = scene.objects[k].states[f + 1];
        // Where holding overlaps a settled box too (it moves into this place), the step back is kept.
        if (!clear && clear_of_settled(after)) {
          scene.objects[k].states[f] = after;
          holding[k] = held[k] = true;
          changed = true;
        }
      }
    }
  }
}

JointScene scenario_gen_log_scene(const Scenario& s) {
  const std::vector<int> tracks = sim_agent_tracks(s);
  JointScene scene = empty_scene(s, tracks);
  for (size_t k = 0; k < tracks.size(); ++k)
    for (const ObjectState& o : s.tracks[tracks[k]].states) scene.objects[k].states.push_back(box_state(o));
  return scene;
}

void round_scene_to_submission(JointScene& scene) {
  for (SceneObject& o : scene.objects)
    for (BoxState& b : o.states)
      for (double* v : {&b.x, &b.y, &b.z, &b.heading, &b.length, &b.width, &b.height})
        *v = static_cast<double>(static_cast<float>(*v));
}

const char* scenario_gen_history_name(ScenarioGenHistory h) {
  return h == ScenarioGenHistory::clear ? "clear" : "constant-velocity";
}

const char* scenario_gen_policy_name(ScenarioGenPolicy p) {
  switch (p) {
    case ScenarioGenPolicy::model: return "model";
    case ScenarioGenPolicy::log_oracle: return "log";
    case ScenarioGenPolicy::placement: return "placement";
    case ScenarioGenPolicy::submission: return "submission";
  }
  return "?";
}

absl::StatusOr<ScenarioGenEvaluation> evaluate_scenario_gen(std::shared_ptr<const Scenario> scenario,
                                                            const ScenarioGenOptions& options,
                                                            std::shared_ptr<const Model> model, MapCache* maps,
                                                            const std::vector<JointScene>* submitted,
                                                            std::vector<JointScene>* scenes) {
  const Scenario& s = *scenario;
  const int now = s.current_time_index;
  if (const std::string p = scenario_gen_problem(s); !p.empty())
    return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, ": ", p));
  if (options.rollouts < 1) return absl::InvalidArgumentError("rollouts must be at least 1");
  const std::vector<int> tracks = sim_agent_tracks(s);
  ScenarioGenEvaluation out;
  out.id = s.id;
  out.sim_agents = static_cast<int>(tracks.size());
  out.requested = scenario_gen_counts(s);
  std::vector<int> all(tracks.size());
  for (size_t k = 0; k < all.size(); ++k) all[k] = static_cast<int>(k);
  std::vector<ObjectType> types;
  for (int t : tracks) types.push_back(s.tracks[t].type);
  const EvalMap map = EvalMap::from_scenario(s);
  const SceneFeatures log_features = scene_features(scenario_gen_log_scene(s), all, map, -1);
  const Pose frame = mmd_frame(s);
  const std::vector<InitialAgent> log_initial = log_initial_agents(s);
  const std::vector<InitialAgent> log_strict = strict_set(log_initial, frame, s);
  const Vec2 centre{frame.x, frame.y};
  out.placed_log = log_placed_agents(s, map.road_edges, centre, std::numeric_limits<double>::infinity(), false);

  std::shared_ptr<const MapContext> context;
  if (options.policy == ScenarioGenPolicy::model) {
    if (!model || !maps) return absl::InvalidArgumentError("the model policy needs a model");
    auto c = maps->get(s);
    if (!c.ok()) return absl::Status(c.status().code(), absl::StrCat("scenario ", s.id, ": ", c.status().message()));
    context = *c;
  }
  if (options.policy == ScenarioGenPolicy::submission && (!submitted || submitted->empty()))
    return absl::InvalidArgumentError(absl::StrCat("scenario ", s.id, ": the submission policy needs rollouts"));
  const int rollouts = options.policy == ScenarioGenPolicy::submission ? static_cast<int>(submitted->size())
                                                                        : options.rollouts;
  std::vector<SceneFeatures> sims;
  std::vector<JointScene> kept;
  std::vector<InitialAgent> pooled_strict, pooled_relaxed;  // every rollout's, for the pooled MMD
  double strict[4] = {}, relaxed[4] = {};
  int n_strict[4] = {}, n_relaxed[4] = {};
  auto add = [](const InitialStateMmd& m, double* sum, int* n) {
    const double v[4] = {m.position, m.heading, m.size, m.velocity};
    for (int i = 0; i < 4; ++i)
      if (std::isfinite(v[i])) sum[i] += v[i], ++n[i];
  };
  for (int k = 0; k < rollouts; ++k) {
    GeneratedScene g;
    const uint64_t seed = rollout_seed(options.session.seed, s.id, k);
    switch (options.policy) {
      case ScenarioGenPolicy::model: {
        SessionOptions o = options.session;
        o.mode = SessionMode::full;
        o.seed = seed;
        const std::array<int, 3> asked = model_request(out.requested, o.max_agents - (has_sdc(s) ? 1 : 0));
        o.agent_counts.assign(asked.begin(), asked.end());
        auto steps = run_model_rollout(model, scenario, context, o, SdcRule::model);
        if (!steps.ok()) return steps.status();
        auto made = generated_scene(s, *steps, asked, options.placement_radius, seed, options.history);
        if (!made.ok()) return made.status();
        g = std::move(*made);
        break;
      }
      case ScenarioGenPolicy::placement: g = placement_scene(s, options.placement_radius, seed); break;
      case ScenarioGenPolicy::log_oracle: g = log_oracle_scene(s); break;
      case ScenarioGenPolicy::submission: {
        g.scene = (*submitted)[k];
        for (size_t i = 0; i < tracks.size(); ++i) {
          const int m = model_type(g.scene.objects[i].type);
          if (!is_sdc(s, tracks[i]) && m >= 0) ++g.placed[m];
        }
        g.overlapping_pairs = overlapping_pairs(g.scene, now);
        break;
      }
    }
    if (options.submission_precision) round_scene_to_submission(g.scene);
    g.initial = initial_agents(s, g.scene);
    out.exact_rollouts += g.placed == out.requested;
    out.filled += g.filled;
    out.overlapping_rollouts += g.overlapping_pairs > 0;
    add(initial_state_mmd(g.initial, log_initial, frame), relaxed, n_relaxed);
    const std::vector<InitialAgent> st = strict_set(g.initial, frame, s);
    pooled_strict.insert(pooled_strict.end(), st.begin(), st.end());
    pooled_relaxed.insert(pooled_relaxed.end(), g.initial.begin(), g.initial.end());
    add(initial_state_mmd(st, log_strict, frame), strict, n_strict);
    const PlacedAgents p = placed_agents(g.initial, {}, s, map.road_edges);
    out.placed_generated += p;
    sims.push_back(scene_features(g.scene, all, map, -1));
    if (scenes) kept.push_back(std::move(g.scene));
  }
  auto mean = [](const double* sum, const int* n) {
    auto m = [&](int i) { return n[i] ? sum[i] / n[i] : kNaN; };
    return InitialStateMmd{m(0), m(1), m(2), m(3)};
  };
  out.mmd_strict = mean(strict, n_strict);
  out.mmd_relaxed = mean(relaxed, n_relaxed);
  out.mmd_pooled_strict = initial_state_mmd(pooled_strict, log_strict, frame);
  out.mmd_pooled_relaxed = initial_state_mmd(pooled_relaxed, log_initial, frame);
  out.rollouts = rollouts;
  out.realism = score_scenario_gen(log_features, sims, types);
  if (scenes) *scenes = std::move(kept);
  return out;
}

ScenarioGenDataset aggregate_scenario_gen(std::span<const ScenarioGenEvaluation> scenarios) {
  ScenarioGenDataset d;
  d.scenarios = static_cast<int>(scenarios.size());
  auto mean_of = [&](auto get) {
    double sum = 0;
    int n = 0;
    for (const ScenarioGenEvaluation& e : scenarios)
      if (const double v = get(e); std::isfinite(v)) sum += v, ++n;
    return n ? sum / n : kNaN;
  };
  for (int f = 0; f < kNumRealismFeatures; ++f)
    d.realism.likelihood[f] = mean_of([&](const ScenarioGenEvaluation& e) { return e.realism.likelihood[f]; });
  d.realism.meta = mean_of([](const ScenarioGenEvaluation& e) { return e.realism.meta; });
  d.realism.kinematic = bucket_score(RealismBucket::kinematic, d.realism.likelihood);
  d.realism.interactive = bucket_score(RealismBucket::interactive, d.realism.likelihood);
  d.realism.map = bucket_score(RealismBucket::map, d.realism.likelihood);
  d.realism.collision_rate = mean_of([](const ScenarioGenEvaluation& e) { return e.realism.collision_rate; });
  d.realism.offroad_rate = mean_of([](const ScenarioGenEvaluation& e) { return e.realism.offroad_rate; });
  d.realism.ade = d.realism.min_ade = kNaN;
  using M = InitialStateMmd;
  for (double M::*field : {&M::position, &M::heading, &M::size, &M::velocity}) {
    d.mmd_strict.*field = mean_of([&](const ScenarioGenEvaluation& e) { return e.mmd_strict.*field; });
    d.mmd_relaxed.*field = mean_of([&](const ScenarioGenEvaluation& e) { return e.mmd_relaxed.*field; });
    d.mmd_pooled_strict.*field = mean_of([&](const ScenarioGenEvaluation& e) { return e.mmd_pooled_strict.*field; });
    d.mmd_pooled_relaxed.*field = mean_of([&](const ScenarioGenEvaluation& e) { return e.mmd_pooled_relaxed.*field; });
  }
  for (const ScenarioGenEvaluation& e : scenarios) {
    d.rollouts = e.rollouts;
    d.filled += e.filled;
    d.total_rollouts += e.rollouts;
    d.exact_rollouts += e.exact_rollouts;
    d.overlapping_rollouts += e.overlapping_rollouts;
    for (auto [a, b] : {std::pair{&d.placed_log, &e.placed_log}, {&d.placed_generated, &e.placed_generated}})
      *a += *b;
  }
  return d;
}

}  // namespace ss
