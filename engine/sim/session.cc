#include "engine/sim/session.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "absl/strings/str_cat.h"
#include "engine/geometry/limits.h"
#include "engine/map/focus.h"
#include "engine/sim/events.h"
#include "engine/sim/sampling.h"
#include "engine/sim/tick.h"
#include "engine/sim/token_builders.h"
#include "engine/tokens/agent_state.h"
#include "engine/tokens/fidelity.h"

namespace ss {

const char* session_mode_name(SessionMode m) {
  switch (m) {
    case SessionMode::motion: return "motion";
    case SessionMode::full: return "full";
    case SessionMode::densify: return "densify";
    case SessionMode::log: return "log";
    case SessionMode::idm: return "idm";
  }
  return "invalid";
}

std::optional<SessionMode> session_mode_from_name(const std::string& name) {
  for (SessionMode m : {SessionMode::motion, SessionMode::full, SessionMode::densify, SessionMode::log, SessionMode::idm})
    if (name == session_mode_name(m)) return m;
  return std::nullopt;
}

namespace {

constexpr int kRejectTries = 6;             // paper appendix D: resample an overlapping new agent at most 6 times
constexpr int kCountTries = 50;             // agent_counts: redraws of an agent that found no free place
// A new agent's tokens (type, end of agents, map segment, relative state) are drawn at options.placement_temperature
// and placement_top_p, the plain softmax by default, as the paper samples every token but motion; the session's
// temperature and top-p shape motion and lights. At the session's 0.7 the end of agents came too rarely once full
// mode began at the current step (165 % of the log's agents on the val scenarios; 80 % at 1.0, with the placed
// vehicles' offroad share 0.468 against the log's 0.466).
constexpr double kMaxStepDistance = 50.0;   // metres in one 0.5 s step (100 m/s): more is a teleport (StateForce)
constexpr double kMaxSpeed = 100.0;         // m/s
constexpr double kRejectBrake = 6.0;        // m/s^2: the braking motion reject sampling leaves room for
// m/s^2: how hard an agent ahead may brake (RSS's a_max_brake), and how hard a controlled agent may brake before its
// next pose arrives: the reject sampler keeps a follower's room to stop behind either.
constexpr double kLeaderBrake = 8.0;
// Steps (3 s) over which a control must not bring an agent, moving on at its new velocity, into a controlled agent
// that repeats its last control or speeds up at kYieldAccel, on the same turn or kYieldTurn to either side: where their
// paths may cross that soon,
// the agent yields (a controlled agent's caller may not yield, and at a stop it may move off at any moment).
constexpr int kYieldSteps = 6;
constexpr double kYieldAccel = 2.0;  // m/s^2
constexpr double kYieldTurn = 0.4;   // rad/s: ... or turning this much more to either side (a turn at an intersection)
constexpr double kRejectTopP = 0.99999;     // a redraw's controls: all but the least likely 0.001 % of the mass
constexpr int kCentreToken = kMotionBins / 2 * kMotionBins + kMotionBins / 2;  // zero acceleration, zero yaw rate

StepState state_from_kin(const KinematicState& k, const StepState& box) {
  StepState s = box;
  s.x = k.x;
  s.y = k.y;
  s.heading = k.heading;
  s.vx = k.speed * std::cos(k.heading);
  s.vy = k.speed * std::sin(k.heading);
  s.valid = true;
  return s;
}

// Whether `a`, braking at kRejectBrake along its velocity from its state now, stops short of `o` moving on at its
// velocity: their boxes are compared every metre or so of a's stopping path, at the same times.
bool stops_short_of(const StepState& a, const StepState& o) {
  const double v = std::hypot(a.vx, a.vy);
  if (v < 0.1) return true;
  const double t_stop = v / kRejectBrake, d_stop = v * t_stop / 2;
  const double vo = std::hypot(o.vx, o.vy);
  const double reach = d_stop + vo * t_stop + (std::hypot(a.length, a.width) + std::hypot(o.length, o.width)) / 2;
  if (std::hypot(a.x - o.x, a.y - o.y) > reach) return true;
  const int samples = std::max(1, static_cast<int>(std::ceil(d_stop)));
  const Vec2 u{a.vx / v, a.vy / v};
  Box ba = box_of(a), bo = box_of(o);
  for (int k = 1; k <= samples; ++k) {
    const double t = t_stop * k / samples, d = v * t - kRejectBrake * t * t / 2;
    ba.pose.x = a.x + d * u.x, ba.pose.y = a.y + d * u.y;
    bo.pose.x = o.x + t * o.vx, bo.pose.y = o.y + t * o.vy;
    if (boxes_overlap(ba, bo)) return false;
  }
  return true;
}
}  // namespace

int Session::effective_window() const {
  const int w = model_->config().window_steps;
  return options_.window_steps > 0 ? std::min(options_.window_steps, w) : w;
}

Vec2 Session::roi_centre() const {
  for (const Agent& a : agents_)
    if (a.controlled) return {a.state.x, a.state.y};
  // No controlled agent: the region follows the SDC while the model drives it (else it would stay where the SDC
  // started, and the SDC itself would retire once it drove roi_radius away).
  const int sdc = scenario_->sdc_track_index;
  if (sdc >= 0)
    for (const Agent& a : agents_)
      if (a.id == scenario_->tracks[sdc].id) return {a.state.x, a.state.y};
  return scenario_focus(*scenario_);
}

bool Session::clear_of_sdc_past(const StepState& a) const {
  const int sdc = scenario_->sdc_track_index;
  if (sdc < 0) return true;
  const Track& t = scenario_->tracks[sdc];
  const int now = step_ * kFramesPerStep;
  Box b = box_of(a);
  for (int f = std::max(0, now - kFramesPerStep * 2); f < now && f < static_cast<int>(t.states.size()); ++f) {
    const ObjectState& o = t.states[f];
    if (!o.valid) continue;
    const double dt = (now - f) * kFrameSeconds;
    b.pose.x = a.x - dt * a.vx, b.pose.y = a.y - dt * a.vy;
    if (boxes_overlap(b, {{o.x, o.y, o.heading}, o.length, o.width})) return false;
  }
  return true;
}

int Session::anchor_segment(const StepState& s) const { return ss::anchor_segment(map_->index, s); }

void Session::undo_to(int cache_size, size_t replay_size) {
  cache_.truncate(cache_size);
  replay_.resize(replay_size);
  if (probe_)
    while (!probe_->batches.empty() && probe_->batches.back().front().seq >= cache_.next_seq) {
      probe_->batches.pop_back();
      probe_->outputs.pop_back();
    }
}

int Session::allocate_slot() {
  const int window = effective_window();
  // A retired agent's slot is reused only once its tokens have left the window, so no two agents alive in one
  // window share an identity embedding.
  for (auto it = released_slots_.begin(); it != released_slots_.end(); ++it)
    if (step_ - it->second >= window) {
      slot_used_[it->first] = false;
      released_slots_.erase(it);
      break;
    }
  for (size_t s = 0; s < slot_used_.size(); ++s) {
    bool released = std::any_of(released_slots_.begin(), released_slots_.end(),
                                [&](const auto& r) { return r.first == static_cast<int>(s); });
    if (!slot_used_[s] && !released) {
      slot_used_[s] = true;
      return static_cast<int>(s);
    }
  }
  return -1;
}

TokenAgent Session::token_agent(const Agent& a) { return {a.id, a.slot, a.type, a.state, a.last_motion}; }

DecoderToken Session::light_token(const Light& l) const {
  return ss::light_token(step_, static_cast<int>(&l - lights_.data()), {l.lane, l.map_id, l.pose}, l.state);
}

void Session::group_tokens(const Agent& a, int order, std::vector<DecoderToken>& out) const {
  const int seg = anchor_segment(a.state);
  agent_group_tokens(step_, token_agent(a), order, seg, map_->segments[seg], out);
}

DecoderToken Session::motion_token(const Agent& a) const { return agent_motion_token(step_, token_agent(a)); }

Mat Session::decode(std::vector<DecoderToken>& tokens) {
  std::vector<int> all(tokens.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return decode(tokens, all);
}

Mat Session::decode(std::vector<DecoderToken>& tokens, std::span<const int> outputs) {
  const int window = effective_window();
  cache_.evict_before(tokens.front().step - window + 1);
  // The probe records every token's output; the caller still gets the rows it asked for.
  Mat h = probe_ ? model_->decode(*map_, cache_, tokens) : model_->decode(*map_, cache_, tokens, outputs);
  replay_.push_back({tokens.front().step, tokens});  // after decode, which assigns the tokens' seq
  if (!probe_) return h;
  probe_->batches.push_back(tokens);
  probe_->outputs.push_back(h);
  return h(outputs, Eigen::all);
}

void Session::trim_replay() {
  // A token's keys at layer l depend on tokens up to l * (W - 1) steps older; keeping L * (W - 1) steps of batches
  // lets restore() rebuild every cached key and value exactly.
  const int keep_from = step_ - model_->config().decoder_layers * (effective_window() - 1);
  size_t drop = 0;
  while (drop < replay_.size() && replay_[drop].step < keep_from) ++drop;
  replay_.erase(replay_.begin(), replay_.begin() + drop);
}

void Session::sample_motions(const Mat& h) {
  if (h.rows() == 0) return;
  const Mat logits = model_->motion_logits(h);
  const auto row = [&](size_t i) { return std::span<const float>(logits.row(i).data(), logits.cols()); };
  for (size_t i = 0; i < agents_.size(); ++i) {
    Agent& a = agents_[i];
    a.next_motion = a.controlled ? -1 : sample_token(row(i), options_.temperature, options_.top_p, rng_);
  }
  if (options_.motion_reject) reject_motion_faults(row);
}

// Reject sampling of motion (the paper's reject sampling of new agents, appendix D, applied to controls). A
// sampled control is refused if it
//   (3) runs the agent's box into another's at the next step (at its end or half-way, as the 10 Hz frames draw it);
//   (2) takes a vehicle whose box is on the road now off it;
//   (1) leaves the agent without room: braking at kRejectBrake, it would not stop short of another moving on at its
//       velocity, nor of where an agent ahead stops braking at kLeaderBrake (RSS's safe longitudinal distance, with
//       response time 0: the follower chooses again at the next step); or, with a controlled agent behind it, it
//       would stop braking at kLeaderBrake where that agent cannot stop short of it; or, moving on at its new
//       velocity, it would meet a controlled agent's course within kYieldSteps (where their paths may cross that
//       soon, the model's agent yields: the caller's ego may not).
// A controlled agent's next pose is unknown: a control must clear both its last control repeated and braking at
// kLeaderBrake from now. Pairs whose boxes overlap already are exempt. A refused agent draws again from its motion
// distribution restricted to the controls with no fault (sample_token_if over kRejectTopP of the mass, not only the
// top-p nucleus: braking hard is often outside it; all 1,089 controls made eval 1.6x slower for realism within
// noise), else with fault 1 only, else faults 1-2; if none passes, it keeps its draw. Agents are visited in order,
// each checking against the others' latest choices. docs/closed-loop.md measures what the rules for controlled
// agents do.
void Session::reject_motion_faults(const std::function<std::span<const float>(size_t)>& row) {
  struct Next {
    Box box;        // at the next step
    Box mid;        // half-way there, as the 10 Hz frames draw it (engine/tokens/resample.h: a straight line)
    Vec2 velocity;  // m/s, at the next step
    double speed;   // signed, along the heading
  };
  const size_t n = agents_.size();
  if (!event_map_) event_map_ = std::make_shared<const EventMap>(event_map_from_scenario(*scenario_));
  const RoadEdges& edges = event_map_->edges;
  // Whether every corner of box b is on the road. `centre_d` is the signed distance of some point p to the road edge
  // and `from_p` how far b's centre is from p: no edge lies within |centre_d| of p, so a box whose corners all lie
  // within that radius of p is on p's side, with no further query; else the same test about b's own centre (unless
  // p is that centre); else its corners.
  const auto on_road = [&](const Box& b, double centre_d, double from_p) {
    const double half_diagonal = norm({b.length, b.width}) / 2;
    if (std::abs(centre_d) > from_p + half_diagonal) return centre_d < 0;
    if (from_p > 0)
      if (const double d = edges.signed_distance(b.pose.x, b.pose.y, 0); std::abs(d) > half_diagonal) return d < 0;
    for (const Vec2& corner : box_corners(b))
      if (edges.signed_distance(corner.x, corner.y, 0) > 0) return false;
    return true;
  };
  const auto next_of = [&](const Agent& a, int token) {
    if (token < 0 || token == kMotionStart) token = kCentreToken;
    const KinematicState k = apply_motion_token(a.kin, token);
    Box mid = box_of(a.state);
    mid.pose = {(a.kin.x + k.x) / 2, (a.kin.y + k.y) / 2,
                std::atan2(std::sin(a.kin.heading) + std::sin(k.heading), std::cos(a.kin.heading) + std::cos(k.heading))};
    return Next{box_of(state_from_kin(k, a.state)), mid, {k.speed * std::cos(k.heading), k.speed * std::sin(k.heading)},
                k.speed};
  };
  const auto moved = [](Box b, Vec2 d) {
    b.pose.x += d.x;
    b.pose.y += d.y;
    return b;
  };
  std::vector<Box> now(n);
  std::vector<Next> next(n);
  std::vector<std::optional<Next>> braked(n);  // controlled agents: their next step braking at kLeaderBrake
  // Controlled agents' courses over kYieldSteps steps: [0] the last control repeated ([0][0] is next[j].box);
  // [1..3] speeding up at kYieldAccel, turning kYieldTurn less than the last control, as much, and more.
  std::vector<std::vector<std::vector<Box>>> courses(n);
  std::vector<double> reach(n);     // no point of the agent's box, braking or not, gets farther from its centre now
  std::vector<int8_t> keep_road(n, -1);  // a vehicle (type 0) on the road now: 1 yes, 0 no, -1 not asked yet
  std::vector<double> edge_d(n);          // signed distance of its centre now to the road edge, once asked
  for (size_t i = 0; i < n; ++i) {
    const Agent& a = agents_[i];
    now[i] = box_of(a.state);
    next[i] = next_of(a, a.controlled ? a.last_motion : a.next_motion);
    if (a.controlled) {
      const double v = std::max(0.0, a.kin.speed), t = std::min(kStepSeconds, v / kLeaderBrake);
      const double d = v * t - kLeaderBrake * t * t / 2, v1 = v - kLeaderBrake * t;
      const Vec2 u{std::cos(a.kin.heading), std::sin(a.kin.heading)};
      Next b{box_of(a.state), box_of(a.state), v1 * u, v1};
      b.box.pose.x += d * u.x, b.box.pose.y += d * u.y;
      b.mid.pose.x += d / 2 * u.x, b.mid.pose.y += d / 2 * u.y;
      braked[i] = b;
      const int token = a.last_motion < 0 || a.last_motion == kMotionStart ? kCentreToken : a.last_motion;
      const double w = motion_yaw_rate(token);
      courses[i].resize(4);
      KinematicState k = a.kin, f[3] = {a.kin, a.kin, a.kin};
      for (int h = 0; h < kYieldSteps; ++h) {
        k = apply_motion_token(k, token);
        courses[i][0].push_back(box_of(state_from_kin(k, a.state)));
        for (int c = 0; c < 3; ++c) {
          f[c] = bicycle_step(f[c], kYieldAccel, w + (c - 1) * kYieldTurn);
          courses[i][c + 1].push_back(box_of(state_from_kin(f[c], a.state)));
        }
      }
    }
    const double v = std::abs(a.kin.speed) + kMaxAccel * kStepSeconds;
    reach[i] = norm({a.state.length, a.state.width}) / 2 + v * kStepSeconds + v * v / (2 * kRejectBrake);
  }
  // The others agent i could touch within the step or while braking, and whose boxes it does not overlap now.
  std::vector<size_t> near;
  const auto find_near = [&](size_t i) {
    near.clear();
    for (size_t j = 0; j < n; ++j)
      if (j != i && distance({now[i].pose.x, now[i].pose.y}, {now[j].pose.x, now[j].pose.y}) <= reach[i] + reach[j] &&
          !boxes_overlap(now[i], now[j]) &&
          !(options_.pedestrian_contact && agents_[i].type == 1 && agents_[j].type == 1))
        near.push_back(j);
  };
  // The three parts of a control's test. Every level asks that its boxes clear the others' next and half-way boxes;
  // level 0 also that they clear them while both brake to a stop; levels 0 and 1 that a vehicle on the road stays
  // on it (the road is looked at last, and only when it can decide: its queries cost the most).
  const auto clears_others = [&](const Next& c) {
    for (size_t j : near) {
      if (boxes_overlap(c.box, next[j].box) || boxes_overlap(c.mid, next[j].mid)) return false;
      if (braked[j] && (boxes_overlap(c.box, braked[j]->box) || boxes_overlap(c.mid, braked[j]->mid))) return false;
    }
    return true;
  };
  const auto clears_braking = [&](size_t i, const Next& c) {
    const double t_stop = std::abs(c.speed) / kRejectBrake;
    const Box stopped = moved(c.box, (t_stop / 2) * c.velocity);
    const Vec2 ahead{std::cos(now[i].pose.heading), std::sin(now[i].pose.heading)};
    const auto leader_stops_clear = [&](const Next& l) {
      const double t = std::abs(l.speed) / kLeaderBrake;
      return !boxes_overlap(stopped, moved(l.box, (t / 2) * l.velocity));
    };
    // Where this agent stops braking at kLeaderBrake: a controlled agent behind it must have room to stop short of
    // it, as its caller may not react (the agents the model drives get that room from their own test).
    const double t_lead = std::abs(c.speed) / kLeaderBrake;
    const Box stopped_as_leader = moved(c.box, (t_lead / 2) * c.velocity);
    for (size_t j : near) {
      if (boxes_overlap(stopped, moved(next[j].box, t_stop * next[j].velocity))) return false;
      const Vec2 to_j{now[j].pose.x - now[i].pose.x, now[j].pose.y - now[i].pose.y};
      if (braked[j] && dot(to_j, Vec2{std::cos(now[j].pose.heading), std::sin(now[j].pose.heading)}) < 0) {
        const double t_follow = std::abs(next[j].speed) / kRejectBrake;
        if (boxes_overlap(stopped_as_leader, moved(next[j].box, (t_follow / 2) * next[j].velocity))) return false;
      }
      if (braked[j]) {
        Box b = c.box;
        for (int h = 1; h < kYieldSteps; ++h) {
          b = moved(b, kStepSeconds * c.velocity);
          for (const std::vector<Box>& course : courses[j])
            if (boxes_overlap(b, course[h])) return false;
        }
      }
      if (dot(to_j, ahead) <= 0) continue;
      if (!leader_stops_clear(next[j]) || (braked[j] && !leader_stops_clear(*braked[j]))) return false;
    }
    return true;
  };
  const auto keeps_road = [&](size_t i, const Next& c) {
    if (agents_[i].type != 0 || edges.empty()) return true;
    if (keep_road[i] < 0) {
      edge_d[i] = edges.signed_distance(now[i].pose.x, now[i].pose.y, 0);
      keep_road[i] = on_road(now[i], edge_d[i], 0);
    }
    return !keep_road[i] ||
           on_road(c.box, edge_d[i], distance({c.box.pose.x, c.box.pose.y}, {now[i].pose.x, now[i].pose.y}));
  };
  // What is known of the controls of the agent being decided. A level that refuses every control hands them all to
  // the next level, which asks only the parts it still checks, each part at most once per control.
  struct Known {
    Next next;
    bool has_next = false;
    int8_t clear = -1, braking = -1, road = -1;  // the parts' answers: 1 yes, 0 no, -1 not asked yet
  };
  std::vector<Known> known;  // by control, sized when first needed (in most steps every first draw passes)
  std::vector<int> asked;    // the controls with an entry in `known`
  const auto control_passes = [&](size_t i, int token, int level) {
    if (known.empty()) known.resize(kMotionTokens);
    Known& k = known[token];
    if (!k.has_next) {
      k.next = next_of(agents_[i], token);
      k.has_next = true;
      asked.push_back(token);
    }
    if (k.clear < 0) k.clear = clears_others(k.next);
    if (!k.clear) return false;
    if (level < 1) {
      if (k.braking < 0) k.braking = clears_braking(i, k.next);
      if (!k.braking) return false;
    }
    if (level >= 2) return true;
    if (k.road < 0) k.road = keeps_road(i, k.next);
    return k.road == 1;
  };
  for (size_t i = 0; i < n; ++i) {
    Agent& a = agents_[i];
    if (a.controlled) continue;
    find_near(i);
    if (clears_others(next[i]) && clears_braking(i, next[i]) && keeps_road(i, next[i])) continue;
    int token = -1;
    for (int level = 0; level < 3 && token < 0; ++level)
      token = sample_token_if(row(i), options_.temperature, kRejectTopP, rng_,
                              [&](int t) { return control_passes(i, t, level); });
    if (token >= 0) {
      a.next_motion = token;
      next[i] = known[token].next;
    }
    for (int t : asked) known[t] = Known{};
    asked.clear();
  }
}

Session::NewAgent Session::sample_agent(const Mat& h_last, bool force_continue, const InjectRequest* req, int order,
                                        int64_t* new_id) {
  const double t = options_.placement_temperature, p = options_.placement_top_p;
  if (static_cast<int>(agents_.size()) >= options_.max_agents) return NewAgent::ended;
  const bool by_count = !quota_.empty();
  if (by_count && std::all_of(quota_.begin(), quota_.end(), [](int n) { return n <= 0; })) return NewAgent::ended;
  if (!force_continue && !by_count) {
    const Mat end = model_->end_of_agents_logits(h_last);
    if (sample_token({end.data(), 2}, t, p, rng_) == 1) return NewAgent::ended;
  }
  const int slot = allocate_slot();
  if (slot < 0) return NewAgent::ended;
  const int cache_before_soa = cache_.size();
  const size_t replay_before_soa = replay_.size();

  Agent a;
  a.id = next_agent_id_;
  a.slot = slot;
  a.entered_step = step_;
  std::vector<DecoderToken> tok;
  DecoderToken soa;
  soa.kind = TokenKind::soa;
  soa.step = step_;
  soa.object = a.id;
  soa.agent_slot = slot;
  soa.intra_index = 4 * order;
  tok = {soa};
  const Mat h_soa = decode(tok);
  if (req && req->type) {
    a.type = *req->type;
  } else {
    Mat type_logits = model_->agent_type_logits(h_soa);
    // By count: only the types still wanted (the model's distribution over them, renormalised).
    if (by_count)
      for (int k = 0; k < kAgentTypes; ++k)
        if (quota_[k] <= 0) type_logits(0, k) = -INFINITY;
    a.type = sample_token({type_logits.data(), kAgentTypes}, t, p, rng_);
  }
  DecoderToken type = soa;
  type.kind = TokenKind::type;
  type.agent_type = a.type;
  type.intra_index = 4 * order + 1;
  tok = {type};
  const Mat h_type = decode(tok);

  StateBins bins{};
  int seg = -1;
  if (req && req->state) {
    a.state = *req->state;
    a.state.valid = true;
    seg = anchor_segment(a.state);
    const RelativeState rel = relative_state(a.state, map_->segments[seg].pose);
    for (int f = 0; f < kRsFields; ++f) bins[f] = state_bin(f, rel[f]);
    DecoderToken ms = type;
    ms.kind = TokenKind::map_segment;
    ms.intra_index = 4 * order + 2;
    ms.has_pose = true;
    ms.pose = map_->segments[seg].pose;
    ms.map_id = seg;
    tok = {ms};
    decode(tok, {});
  } else {
    // Where a new agent may appear: within the region of interest, and where the request says.
    Mat pointer = model_->map_segment_logits(h_type, *map_);
    const Vec2 centre = roi_centre();
    bool any = false;
    for (int j = 0; j < map_->size(); ++j) {
      const Vec2 p{map_->segments[j].pose.x, map_->segments[j].pose.y};
      bool ok = distance(p, centre) <= options_.roi_radius;
      if (req && req->near) ok = ok && distance(p, *req->near) <= req->near_radius;
      if (req && req->segment) ok = j == *req->segment;
      if (!ok) pointer(0, j) = -INFINITY;
      any = any || ok;
    }
    if (!any) {
      undo_to(cache_before_soa, replay_before_soa);
      slot_used_[slot] = false;
      return NewAgent::ended;
    }
    bool placed = false;
    for (int attempt = 0; attempt < kRejectTries && !placed; ++attempt) {
      const int cache_before_ms = cache_.size();
      const size_t replay_before_ms = replay_.size();
      seg = sample_token({pointer.data(), static_cast<size_t>(pointer.cols())}, t, p, rng_);
      DecoderToken ms = type;
      ms.kind = TokenKind::map_segment;
      ms.intra_index = 4 * order + 2;
      ms.has_pose = true;
      ms.pose = map_->segments[seg].pose;
      ms.map_id = seg;
      tok = {ms};
      const Mat h_ms = decode(tok);
      RsHead head = model_->rs_begin(h_ms);
      for (int f = 0; f < kRsFields; ++f) {
        const Vec logits = model_->rs_next(head, f == 0 ? 0 : bins[f - 1]);
        bins[f] = sample_token({logits.data(), static_cast<size_t>(logits.size())}, t, p, rng_);
      }
      RelativeState rel;
      for (int f = 0; f < kRsFields; ++f) rel[f] = state_bin_value(f, bins[f]);
      a.state = global_state(rel, map_->segments[seg].pose);
      // Clear of every box, by options.placement_clearance metres on each side (0: not overlapping).
      Box mine = box_of(a.state);
      mine.length += 2 * options_.placement_clearance, mine.width += 2 * options_.placement_clearance;
      placed = std::none_of(agents_.begin(), agents_.end(),
                            [&](const Agent& o) { return boxes_overlap(box_of(o.state), mine); });
      if (placed && options_.placement_room)
        placed = std::all_of(agents_.begin(), agents_.end(), [&](const Agent& o) {
          return stops_short_of(a.state, o.state) && stops_short_of(o.state, a.state);
        }) && (!by_count || clear_of_sdc_past(a.state));
      if (!placed) undo_to(cache_before_ms, replay_before_ms);
    }
    if (!placed) {
      undo_to(cache_before_soa, replay_before_soa);
      slot_used_[slot] = false;
      return NewAgent::dropped;
    }
  }
  DecoderToken rs = type;
  rs.kind = TokenKind::relative_state;
  rs.intra_index = 4 * order + 3;
  rs.has_pose = true;
  rs.pose = {a.state.x, a.state.y, a.state.heading};
  rs.map_id = seg;
  rs.relative_state = scaled_relative_state(bins);
  tok = {rs};
  const Mat h_rs = decode(tok);
  a.kin = kinematic_state(a.state);
  a.last_motion = kMotionStart;
  agents_.push_back(a);
  entered_.push_back(a.id);
  ++next_agent_id_;
  *new_id = a.id;
  last_group_output_ = h_rs;
  return NewAgent::placed;
}

absl::Status Session::decode_step(bool sample_lights, bool allow_new, int force_new,
                                  const std::vector<InjectRequest>& inject, std::vector<int64_t>* injected) {
  // Batch 1: the lights and the agent-state group of the agents already present (state-forced).
  std::vector<DecoderToken> tokens;
  for (const Light& l : lights_) tokens.push_back(light_token(l));
  const int num_lights = static_cast<int>(tokens.size());
  tokens.push_back(sos_token(step_));
  for (size_t i = 0; i < agents_.size(); ++i) group_tokens(agents_[i], static_cast<int>(i), tokens);
  // Outputs read: the lights' (their next states) and the group's last token's (whether another agent follows).
  std::vector<int> outputs;
  if (sample_lights)
    for (int i = 0; i < num_lights; ++i) outputs.push_back(i);
  outputs.push_back(static_cast<int>(tokens.size()) - 1);
  const Mat h = decode(tokens, outputs);
  if (sample_lights) sample_light_states(h.topRows(num_lights));
  last_group_output_ = h.bottomRows(1);
  // Then new agents, one token at a time; then batch 2, EOS and every agent's motion token.
  if (auto st = add_agents(allow_new, force_new, inject, injected); !st.ok()) return st;
  finish_step();
  return absl::OkStatus();
}

absl::Status Session::add_agents(bool allow_new, int force_new, const std::vector<InjectRequest>& inject,
                                 std::vector<int64_t>* injected) {
  for (const InjectRequest& req : inject) {
    const int count = req.state ? 1 : req.count;
    for (int n = 0; n < count; ++n) {
      int64_t id = 0;
      if (sample_agent(last_group_output_, true, &req, static_cast<int>(agents_.size()), &id) != NewAgent::placed)
        return absl::ResourceExhaustedError(absl::StrCat(
            "could not place injected agent ", n + 1, " of ", count, ": the agent cap (", options_.max_agents,
            ") is reached, or no free place was found within the region after ", kRejectTries, " tries"));
      if (injected) injected->push_back(id);
    }
  }
  // An agent that found no free place is dropped and the group goes on (the paper regenerates an agent that
  // overlaps another): ending the group there cut dense scenes short, since the more agents a region holds, the
  // likelier a draw lands on one. Only a run of kRejectTries drops in a row ends it (a region with no room left).
  auto fill = [&](bool force_continue, int wanted) {
    for (int placed = 0, dropped = 0; placed < wanted && dropped < kRejectTries;) {
      int64_t id = 0;
      const NewAgent r = sample_agent(last_group_output_, force_continue, nullptr, static_cast<int>(agents_.size()), &id);
      if (r == NewAgent::ended) return;
      if (r == NewAgent::placed) {
        ++placed;
        dropped = 0;
      } else {
        ++dropped;
      }
    }
  };
  if (!quota_.empty()) {
    // By count: every requested agent is placed. A draw that finds no free place is redrawn (its type and segment
    // too); only a region with no room left for kCountTries draws in a row is an error.
    int wanted = 0;
    for (int n : quota_) wanted += n;
    for (int placed = 0, dropped = 0; placed < wanted;) {
      int64_t id = 0;
      const NewAgent r = sample_agent(last_group_output_, true, nullptr, static_cast<int>(agents_.size()), &id);
      if (r == NewAgent::placed) {
        --quota_[agents_.back().type];
        ++placed;
        dropped = 0;
        continue;
      }
      if (r == NewAgent::ended || ++dropped >= kCountTries)
        return absl::ResourceExhaustedError(absl::StrCat(
            "agent_counts: placed ", placed, " of the ", wanted, " agents requested; no free place for another within ",
            options_.roi_radius, " m after ", kCountTries, " draws (", kRejectTries, " tries each)"));
    }
    return absl::OkStatus();
  }
  fill(true, force_new);
  if (allow_new) fill(false, std::numeric_limits<int>::max());
  return absl::OkStatus();
}

void Session::finish_step() {
  eos_cache_size_ = cache_.size();
  std::vector<DecoderToken> tokens;
  tokens.push_back(eos_token(step_));
  std::vector<int> motion_rows;
  for (const Agent& a : agents_) {
    motion_rows.push_back(static_cast<int>(tokens.size()));
    tokens.push_back(motion_token(a));
  }
  sample_motions(decode(tokens, motion_rows));
}

void Session::sample_light_states(const Mat& h) {
  if (h.rows() == 0) return;
  const Mat logits = model_->light_logits(h);
  for (size_t k = 0; k < lights_.size(); ++k)
    lights_[k].next_state = static_cast<LightState>(
        sample_token({logits.row(k).data(), kLightStates}, options_.temperature, 1.0, rng_));
}

}  // namespace ss

namespace ss {

absl::Status Session::check_state(const StepState& s, const std::string& what) const {
  const std::pair<double, const char*> fields[] = {{s.x, "x"},   {s.y, "y"},         {s.heading, "heading"},
                                                   {s.vx, "vx"}, {s.vy, "vy"},       {s.length, "length"},
                                                   {s.width, "width"}, {s.height, "height"}};
  for (const auto& [v, name] : fields)
    if (!std::isfinite(v))
      return absl::InvalidArgumentError(absl::StrCat(what, ": ", name, " is ", v, ", not a finite number"));
  if (std::abs(s.x) > kMaxCoordinate || std::abs(s.y) > kMaxCoordinate)
    return absl::InvalidArgumentError(absl::StrCat(what, " lies beyond ", kMaxCoordinate, " m"));
  if (s.length <= 0 || s.width <= 0 || s.height <= 0 || s.length > 30 || s.width > 10 || s.height > 10)
    return absl::InvalidArgumentError(absl::StrCat(what, " has an implausible box ", s.length, " x ", s.width, " x ",
                                                   s.height, " m"));
  if (std::abs(s.heading) > kMaxHeading)
    return absl::InvalidArgumentError(absl::StrCat(what, " has a heading of ", s.heading, " rad, beyond +-", kMaxHeading));
  if (std::hypot(s.vx, s.vy) > kMaxSpeed)
    return absl::InvalidArgumentError(absl::StrCat(what, " moves faster than ", kMaxSpeed, " m/s"));
  return absl::OkStatus();
}

absl::Status Session::check_controls(const std::vector<ControlInput>& controls) const {
  std::set<int64_t> seen;
  for (const ControlInput& c : controls) {
    const std::string what = absl::StrCat("control for agent ", c.agent_id);
    auto it = std::find_if(agents_.begin(), agents_.end(), [&](const Agent& a) { return a.id == c.agent_id; });
    if (it == agents_.end()) return absl::InvalidArgumentError(absl::StrCat(what, ": no such agent in the session"));
    if (!it->controlled) return absl::InvalidArgumentError(absl::StrCat(what, ": the agent is not a controlled agent"));
    if (!seen.insert(c.agent_id).second) return absl::InvalidArgumentError(absl::StrCat(what, ": given twice"));
    const std::pair<double, const char*> values[] = {
        {c.x, "x"}, {c.y, "y"}, {c.heading, "heading"}, {c.speed.value_or(0), "speed"}};
    for (const auto& [v, name] : values)
      if (!std::isfinite(v))
        return absl::InvalidArgumentError(absl::StrCat(what, ": ", name, " is ", v, ", not a finite number"));
    if (std::abs(c.x) > kMaxCoordinate || std::abs(c.y) > kMaxCoordinate)
      return absl::InvalidArgumentError(absl::StrCat(what, ": pose lies beyond ", kMaxCoordinate, " m"));
    if (std::abs(c.heading) > kMaxHeading)
      return absl::InvalidArgumentError(absl::StrCat(what, ": heading ", c.heading, " rad is beyond +-", kMaxHeading));
    const double jump = std::hypot(c.x - it->state.x, c.y - it->state.y);
    if (jump > kMaxStepDistance)
      return absl::InvalidArgumentError(absl::StrCat(what, ": pose is ", jump, " m from the last one; at most ",
                                                     kMaxStepDistance, " m per 0.5 s step (use StateForce to teleport)"));
    if (c.speed && (*c.speed < 0 || *c.speed > kMaxSpeed))
      return absl::InvalidArgumentError(absl::StrCat(what, ": speed ", *c.speed, " m/s is outside 0..", kMaxSpeed,
                                                     " (a speed is along the heading)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<StepResult> Session::tick(const std::vector<ControlInput>& controls) {
  // Check everything first, once per tick: a bad input leaves the session as it was.
  if (auto st = check_controls(controls); !st.ok()) return st;
  // The events are measured from the tick before this one (a stop line crossed, progress along the lane).
  const bool any_controlled = std::any_of(agents_.begin(), agents_.end(), [](const Agent& a) { return a.controlled; });
  std::optional<StepResult> before;
  if (any_controlled) before = tick_view();
  auto r = advance_tick(controls);
  if (!r.ok() || !any_controlled) return r;
  if (!event_map_) event_map_ = std::make_shared<const EventMap>(event_map_from_scenario(*scenario_));
  r->events = tick_events(*event_map_, *before, *r);
  return r;
}

absl::StatusOr<StepResult> Session::advance_tick(const std::vector<ControlInput>& controls) {
  if (options_.tick_hz == 2) {
    auto r = step_checked(controls);
    if (r.ok()) ++tick_;
    return r;
  }
  std::map<int64_t, ControlInput> step_controls = step_controls_;
  for (const ControlInput& c : controls) step_controls[c.agent_id] = c;
  if ((tick_ + 1) % ticks_per_step() == 0) {
    std::vector<ControlInput> at_step;
    for (const auto& [id, c] : step_controls) at_step.push_back(c);
    auto r = step_checked(at_step);
    if (!r.ok()) return r.status();
    for (const ControlInput& c : controls) latest_pose_[c.agent_id] = c;
    step_controls_.clear();
    ++tick_;
    return r;
  }
  for (const ControlInput& c : controls) latest_pose_[c.agent_id] = c;
  step_controls_ = std::move(step_controls);
  ++tick_;
  return tick_view();
}

StepResult Session::tick_view() const {
  const int n = ticks_per_step();
  if (n <= 1 || tick_ % n == 0) return current();
  std::vector<ControlInput> pushed;
  for (const auto& [id, c] : latest_pose_) pushed.push_back(c);
  return tick_between_steps(*this, static_cast<int>(tick_ % n), n, pushed);
}

absl::StatusOr<StepResult> Session::step(const std::vector<ControlInput>& controls) {
  // Check everything first: a bad input leaves the session as it was.
  if (auto st = check_controls(controls); !st.ok()) return st;
  return step_checked(controls);
}

absl::StatusOr<StepResult> Session::step_checked(const std::vector<ControlInput>& controls) {
  std::map<int64_t, const ControlInput*> by_id;
  for (const ControlInput& c : controls) by_id.emplace(c.agent_id, &c);

  left_.clear();
  std::set<int64_t> leaving;  // rule modes: agents their log has no state for at the next step
  for (Agent& a : agents_) {
    if (rule_mode() && !a.controlled) {
      if (!a.planned) {
        leaving.insert(a.id);
        continue;
      }
      a.state = *a.planned;
      a.kin = kinematic_state(a.state);
      a.path_s = a.planned_s;
    } else if (a.forced) {
      a.state = *a.forced;
      a.kin = kinematic_state(a.state);
      a.last_motion = kMotionStart;  // a teleport: the agent starts afresh where it was put
      a.forced.reset();
    } else if (auto it = by_id.find(a.id); it != by_id.end()) {
      const ControlInput& c = *it->second;
      const MotionFit fit = fit_motion_token(a.kin, {c.x, c.y, wrap_angle(c.heading)}, a.state.length, a.state.width);
      a.last_motion = fit.token;
      a.kin = {c.x, c.y, wrap_angle(c.heading), c.speed ? *c.speed : fit.state.speed};
      a.state = state_from_kin(a.kin, a.state);
    } else {
      // A controlled agent without a pose keeps its last control; others take the sampled one.
      int token = a.controlled ? a.last_motion : a.next_motion;
      if (token < 0 || token == kMotionStart) token = kCentreToken;
      a.last_motion = token;
      a.kin = apply_motion_token(a.kin, token);
      a.state = state_from_kin(a.kin, a.state);
    }
  }
  for (Light& l : lights_) {
    l.state = l.forced ? *l.forced : l.next_state;
    l.forced.reset();
  }
  ++step_;
  entered_.clear();
  if (rule_mode()) {
    for (auto it = agents_.begin(); it != agents_.end();) {
      if (leaving.count(it->id)) {
        left_.push_back(it->id);
        it = agents_.erase(it);
      } else {
        ++it;
      }
    }
    join_logged_agents();
    plan_rule_agents();
    return current();
  }
  // Agents that left the region of interest retire; their slots are recycled once out of the window.
  const Vec2 centre = roi_centre();
  for (auto it = agents_.begin(); it != agents_.end();) {
    // Placed by count, the scene is the requested agents throughout: none retires.
    if (!it->controlled && options_.agent_counts.empty() && distance({it->state.x, it->state.y}, centre) > options_.roi_radius) {
      left_.push_back(it->id);
      released_slots_.push_back({it->slot, step_});
      it = agents_.erase(it);
    } else {
      ++it;
    }
  }
  trim_replay();
  const bool allow_new = options_.mode != SessionMode::motion && options_.agent_counts.empty();
  if (auto st = decode_step(true, allow_new, 0, {}, nullptr); !st.ok()) return st;
  return current();
}

absl::StatusOr<std::vector<int64_t>> Session::inject(const InjectRequest& req) {
  if (rule_mode())
    return absl::FailedPreconditionError(absl::StrCat("inject: a ", session_mode_name(options_.mode),
                                                      " session moves only its log's agents (inject needs a model mode)"));
  if (req.state) {
    if (req.count != 0 && req.count != 1)
      return absl::InvalidArgumentError("inject: give either a count or a state, not both");
    if (auto st = check_state(*req.state, "inject: state"); !st.ok()) return st;
  } else if (req.count < 1 || req.count > model_->config().agent_slots) {
    return absl::InvalidArgumentError(absl::StrCat("inject: count ", req.count, " is outside 1..",
                                                   model_->config().agent_slots));
  }
  if (req.type && (*req.type < 0 || *req.type >= kAgentTypes))
    return absl::InvalidArgumentError(absl::StrCat("inject: type ", *req.type, " is not 0 (vehicle), 1 (pedestrian) or 2 (cyclist)"));
  if (req.near && (!std::isfinite(req.near->x) || !std::isfinite(req.near->y) || !(req.near_radius > 0)))
    return absl::InvalidArgumentError("inject: near point or radius is not a finite positive value");
  if (req.segment && (*req.segment < 0 || *req.segment >= map_->size()))
    return absl::InvalidArgumentError(absl::StrCat("inject: segment ", *req.segment, " is outside the map's ",
                                                   map_->size(), " segments"));
  const int count = req.state ? 1 : req.count;
  if (static_cast<int>(agents_.size()) + count > options_.max_agents)
    return absl::ResourceExhaustedError(absl::StrCat("inject: ", count, " more agents would exceed the cap of ",
                                                     options_.max_agents, " (", agents_.size(), " alive)"));

  // Undo the step's EOS and motion batch, add the agents to the group, and decode EOS and motion again.
  Session backup(*this);
  undo_to(eos_cache_size_, replay_.size() - 1);
  std::vector<int64_t> ids;
  if (auto st = add_agents(false, 0, {req}, &ids); !st.ok()) {
    *this = std::move(backup);
    undo_to(cache_.size(), replay_.size());  // drops the failed attempt's batches from a test probe
    return st;
  }
  finish_step();
  return ids;
}

absl::Status Session::state_force(const StateForceRequest& req) {
  std::set<int64_t> seen_agents, seen_lights;
  for (const auto& entry : req.agents) {
    const int64_t id = entry.first;
    const StepState& s = entry.second;
    if (std::none_of(agents_.begin(), agents_.end(), [&](const Agent& a) { return a.id == id; }))
      return absl::InvalidArgumentError(absl::StrCat("state force: no agent ", id, " in the session"));
    if (!seen_agents.insert(id).second) return absl::InvalidArgumentError(absl::StrCat("state force: agent ", id, " given twice"));
    if (rule_mode() && std::none_of(agents_.begin(), agents_.end(), [&](const Agent& a) { return a.id == id && a.controlled; }))
      return absl::FailedPreconditionError(absl::StrCat("state force: agent ", id, " follows its log in a ",
                                                        session_mode_name(options_.mode),
                                                        " session; only controlled agents can be placed"));
    if (auto st = check_state(s, absl::StrCat("state force: agent ", id)); !st.ok()) return st;
  }
  for (const auto& entry : req.lights) {
    const int64_t lane = entry.first;
    const LightState state = entry.second;
    if (std::none_of(lights_.begin(), lights_.end(), [&](const Light& l) { return l.lane == lane; }))
      return absl::InvalidArgumentError(absl::StrCat("state force: no light on lane ", lane));
    if (static_cast<int>(state) >= kLightStates)  // an unsigned byte: only too large is possible
      return absl::InvalidArgumentError(absl::StrCat("state force: light state ", static_cast<int>(state), " is not 0..3"));
    if (!seen_lights.insert(lane).second) return absl::InvalidArgumentError(absl::StrCat("state force: lane ", lane, " given twice"));
  }
  for (const auto& [id, s] : req.agents)
    for (Agent& a : agents_)
      if (a.id == id) {
        a.forced = s;
        a.forced->valid = true;
      }
  for (const auto& [lane, state] : req.lights)
    for (Light& l : lights_)
      if (l.lane == lane) l.forced = state;
  return absl::OkStatus();
}

std::unique_ptr<Session> Session::fork() const {
  auto copy = std::unique_ptr<Session>(new Session(*this));
  copy->probe_ = nullptr;
  return copy;
}

StepResult Session::current() const {
  StepResult r;
  r.step = step_;
  r.time = step_ * kStepSeconds;
  for (const Agent& a : agents_) r.agents.push_back({a.id, a.type, a.state, a.controlled, a.entered_step == step_});
  for (const Light& l : lights_) r.lights.push_back({l.lane, l.state, l.pose});
  r.left = left_;
  return r;
}

StepResult Session::sub_tick_view(int sub_tick, int ticks_per_step) const {
  StepResult r = current();
  if (sub_tick <= 0) return r;
  // (0.5 k) / n: at k == n this is exactly kStepSeconds, the dt step() uses, so the end point is step()'s to the bit.
  const double t = kStepSeconds * sub_tick / ticks_per_step;
  r.time += t;
  r.left.clear();
  for (size_t i = 0; i < agents_.size(); ++i) {  // current() lists the agents in this order
    const Agent& a = agents_[i];
    AgentView& v = r.agents[i];
    v.entered = false;
    if (a.controlled) continue;  // its client's pushed pose is the host's to show (tick_between_steps)
    if (rule_mode()) {
      if (!a.planned) continue;  // it leaves at the step: shown where it is until then
      const double f = static_cast<double>(sub_tick) / ticks_per_step;
      v.state.x += f * (a.planned->x - a.state.x);
      v.state.y += f * (a.planned->y - a.state.y);
      v.state.heading = wrap_angle(a.state.heading + f * wrap_angle(a.planned->heading - a.state.heading));
      if (sub_tick == ticks_per_step) v.state = *a.planned;
      continue;
    }
    if (a.forced) {
      // step() will teleport it whatever it sampled; until then it moves on at its last velocity instead of jumping.
      v.state.x += v.state.vx * t;
      v.state.y += v.state.vy * t;
      continue;
    }
    // The control step() applies to it, the same fallback included.
    const int token = a.next_motion < 0 || a.next_motion == kMotionStart ? kCentreToken : a.next_motion;
    v.state = state_from_kin(bicycle_step(a.kin, motion_accel(token), motion_yaw_rate(token), t), a.state);
  }
  return r;
}

size_t Session::memory_bytes() const {
  size_t b = sizeof(*this) + cache_.bytes() + agents_.capacity() * sizeof(Agent) + lights_.capacity() * sizeof(Light);
  for (const Batch& batch : replay_) b += sizeof(Batch) + batch.tokens.capacity() * sizeof(DecoderToken);
  if (paths_)
    for (const LoggedPath& p : *paths_)
      b += sizeof(LoggedPath) + p.points.capacity() * sizeof(Vec2) +
           (p.s.capacity() + p.heading.capacity()) * sizeof(double) + p.frame.capacity() * sizeof(int);
  return b;
}

}  // namespace ss
