// Session save and restore. The byte form holds the session's own state (options, RNG, agents, lights) and the
// decoder batches of the last L * (W - 1) steps; restore() re-runs those batches, in the same batches, which
// rebuilds every key and value the cache holds bit for bit (keys at layer l depend on tokens at most l * (W - 1)
// steps older), so a restored session continues exactly as the saved one would have.
// Layout: the project's one framed record (engine/io/record.h) of kSessionStateMagic and one ss.state.SessionState
// message (proto/state/session_state.proto). The framing makes a truncated or corrupted state an error: a protobuf
// message cut at a field boundary still parses, and would restore a session missing its last fields. States in the
// layout before the framing (the magic, the message's FNV-1a hash, the message) are still read.
#include <cmath>
#include <cstring>
#include <string_view>

#include "absl/strings/str_cat.h"
#include "engine/io/record.h"
#include "engine/sim/session.h"
#include "state/session_state.pb.h"

namespace ss {
namespace {

// kSessionStateMagic without its terminating NUL; its last character is the version.
constexpr RecordFormat kFormat{std::string_view(kSessionStateMagic, sizeof kSessionStateMagic - 1), 1,
                               "session snapshot", "engine", RecordFormat::Earlier::hash_then_message};

void put_pose(state::Pose* p, double x, double y, double heading) {
  p->set_x(x);
  p->set_y(y);
  p->set_heading(heading);
}

void put_state(state::StepState* p, const StepState& s) {
  p->set_x(s.x);
  p->set_y(s.y);
  p->set_heading(s.heading);
  p->set_vx(s.vx);
  p->set_vy(s.vy);
  p->set_length(s.length);
  p->set_width(s.width);
  p->set_height(s.height);
  p->set_valid(s.valid);
}

StepState get_state(const state::StepState& p) {
  StepState s;
  s.x = p.x(), s.y = p.y(), s.heading = p.heading(), s.vx = p.vx(), s.vy = p.vy();
  s.length = p.length(), s.width = p.width(), s.height = p.height(), s.valid = p.valid();
  return s;
}

bool finite_state(const StepState& s) {
  for (double v : {s.x, s.y, s.heading, s.vx, s.vy, s.length, s.width, s.height})
    if (!std::isfinite(v)) return false;
  return true;
}

// A fingerprint of the map tokens' geometry, so a save is not restored onto another map.
uint64_t map_fingerprint(const MapContext& map) {
  uint64_t h = kFnv1aOffset;
  auto mix = [&](double v) { h = fnv1a64_bytes(&v, sizeof v, h); };
  for (const MapSegment& s : map.segments) mix(s.pose.x), mix(s.pose.y), mix(s.pose.heading);
  return h;
}

}  // namespace

std::string Session::save() const {
  state::SessionState m;
  m.set_scenario_id(scenario_->id);
  m.set_map_size(map_->size());
  m.set_map_fingerprint(map_fingerprint(*map_));
  state::Options* o = m.mutable_options();
  o->set_mode(static_cast<int32_t>(options_.mode));
  o->set_seed(options_.seed);
  o->set_top_p(options_.top_p);
  o->set_temperature(options_.temperature);
  o->set_max_agents(options_.max_agents);
  o->set_roi_radius(options_.roi_radius);
  o->set_window_steps(options_.window_steps);
  for (int32_t id : options_.controlled_ids) o->add_controlled_ids(id);
  o->set_densify_target(options_.densify_target);
  o->set_control_sdc(options_.control_sdc);
  o->set_tick_hz(options_.tick_hz);
  o->set_motion_reject(options_.motion_reject);
  for (int n : options_.agent_counts) o->add_agent_counts(n);
  o->set_placement_temperature(options_.placement_temperature);
  o->set_placement_top_p(options_.placement_top_p);
  o->set_placement_clearance(options_.placement_clearance);
  o->set_placement_room(options_.placement_room);
  o->set_pedestrian_contact(options_.pedestrian_contact);
  m.set_tick(tick_);
  for (auto [poses, out] : {std::pair{&latest_pose_, m.mutable_latest_pose()},
                            std::pair{&step_controls_, m.mutable_step_controls()}}) {
    for (const auto& [id, c] : *poses) {
      state::PushedPose* p = out->Add();
      p->set_agent_id(c.agent_id);
      p->set_x(c.x);
      p->set_y(c.y);
      p->set_heading(c.heading);
      if (c.speed) p->set_speed(*c.speed);
    }
  }

  for (uint64_t w : rng_.s) m.add_rng(w);
  m.set_step(step_);
  m.set_next_agent_id(next_agent_id_);
  m.set_eos_cache_size(eos_cache_size_);
  for (const Agent& a : agents_) {
    state::Agent* p = m.add_agents();
    p->set_id(a.id);
    p->set_type(a.type);
    p->set_slot(a.slot);
    put_state(p->mutable_state(), a.state);
    put_pose(p->mutable_kin(), a.kin.x, a.kin.y, a.kin.heading);
    p->set_kin_speed(a.kin.speed);
    p->set_last_motion(a.last_motion);
    p->set_next_motion(a.next_motion);
    p->set_controlled(a.controlled);
    p->set_entered_step(a.entered_step);
    if (a.forced) put_state(p->mutable_forced(), *a.forced);
    p->set_path_s(a.path_s);
  }
  for (const Light& l : lights_) {
    state::Light* p = m.add_lights();
    p->set_lane(l.lane);
    p->set_map_id(l.map_id);
    put_pose(p->mutable_pose(), l.pose.x, l.pose.y, l.pose.heading);
    p->set_state(static_cast<int32_t>(l.state));
    p->set_next_state(static_cast<int32_t>(l.next_state));
    if (l.forced) p->set_forced(static_cast<int32_t>(*l.forced));
  }
  for (int64_t id : left_) m.add_left(id);
  for (const auto& [slot, at] : released_slots_) {
    state::ReleasedSlot* p = m.add_released_slots();
    p->set_slot(slot);
    p->set_step(at);
  }
  for (bool u : slot_used_) m.add_slot_used(u);

  for (const Batch& b : replay_) {
    state::Batch* pb = m.add_replay();
    pb->set_step(b.step);
    for (const DecoderToken& t : b.tokens) {
      state::Token* p = pb->add_tokens();
      p->set_kind(static_cast<int32_t>(t.kind));
      p->set_seq(t.seq);
      p->set_step(t.step);
      p->set_object(t.object);
      p->set_posed(t.has_pose);
      put_pose(p->mutable_pose(), t.pose.x, t.pose.y, t.pose.heading);
      p->set_agent_slot(t.agent_slot);
      p->set_agent_type(t.agent_type);
      p->set_intra_index(t.intra_index);
      p->set_light_slot(t.light_slot);
      p->set_light_state(t.light_state);
      p->set_map_id(t.map_id);
      p->set_motion_action(t.motion_action);
      p->mutable_motion_state()->Add(t.motion_state.begin(), t.motion_state.end());
      p->mutable_relative_state()->Add(t.relative_state.begin(), t.relative_state.end());
    }
  }
  return record_write(kFormat, m.SerializeAsString());
}

absl::StatusOr<std::unique_ptr<Session>> Session::restore(std::shared_ptr<const Model> model,
                                                          std::shared_ptr<const Scenario> scenario,
                                                          std::shared_ptr<const MapContext> map,
                                                          const std::string& bytes) {
  auto bad = [](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat("session snapshot: ", what));
  };
  auto message = record_read(kFormat, bytes);
  if (!message.ok()) return message.status();
  state::SessionState m;
  if (!m.ParseFromArray(message->data(), static_cast<int>(message->size())))
    return bad("the state message does not parse");
  const ModelConfig& c = model->config();
  auto s = std::unique_ptr<Session>(new Session());
  s->model_ = model;
  s->scenario_ = scenario;
  s->map_ = map;

  if (m.scenario_id() != scenario->id)
    return bad(absl::StrCat("saved for scenario ", m.scenario_id(), ", restoring onto ", scenario->id));
  if (m.map_size() != map->size() || m.map_fingerprint() != map_fingerprint(*map))
    return bad("saved on a different map encoding (segments differ)");
  SessionOptions& o = s->options_;
  const state::Options& mo = m.options();
  const int32_t mode = mo.mode();
  o.mode = static_cast<SessionMode>(mode);
  o.seed = mo.seed();
  o.top_p = mo.top_p();
  o.temperature = mo.temperature();
  o.max_agents = mo.max_agents();
  o.roi_radius = mo.roi_radius();
  o.window_steps = mo.window_steps();
  o.controlled_ids.assign(mo.controlled_ids().begin(), mo.controlled_ids().end());
  o.densify_target = mo.densify_target();
  o.control_sdc = mo.control_sdc();
  o.tick_hz = mo.tick_hz();
  o.motion_reject = mo.motion_reject();
  o.agent_counts.assign(mo.agent_counts().begin(), mo.agent_counts().end());
  o.placement_temperature = mo.has_placement_temperature() ? mo.placement_temperature() : 1.0;
  o.placement_top_p = mo.has_placement_top_p() ? mo.placement_top_p() : 1.0;
  o.placement_clearance = mo.placement_clearance();
  o.placement_room = mo.placement_room();
  o.pedestrian_contact = mo.pedestrian_contact();
  s->tick_ = m.tick();
  if (o.tick_hz != 2 && o.tick_hz != 10) return bad(absl::StrCat("tick_hz ", o.tick_hz, " (only 2 or 10)"));
  if (s->tick_ < 0) return bad("negative tick");
  for (auto [in, poses] : {std::pair{&m.latest_pose(), &s->latest_pose_},
                           std::pair{&m.step_controls(), &s->step_controls_}}) {
    for (const state::PushedPose& p : *in) {
      ControlInput c;
      c.agent_id = p.agent_id();
      c.x = p.x(), c.y = p.y(), c.heading = p.heading();
      if (p.has_speed()) c.speed = p.speed();
      if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.heading) || !std::isfinite(p.speed()))
        return bad(absl::StrCat("pushed pose of agent ", c.agent_id, " has a non-finite value"));
      if (!poses->emplace(c.agent_id, c).second)
        return bad(absl::StrCat("two pushed poses of agent ", c.agent_id));
    }
  }
  if (mode < 0 || mode > 4 || !(o.temperature > 0) || !(o.top_p > 0 && o.top_p <= 1) || o.max_agents < 1 ||
      o.max_agents > c.agent_slots || !(o.roi_radius > 0) || o.window_steps < 0 || o.window_steps > c.window_steps)
    return bad("options out of range");

  if (m.rng_size() != static_cast<int>(s->rng_.s.size())) return bad("the random generator's state is not 4 words");
  std::copy(m.rng().begin(), m.rng().end(), s->rng_.s.begin());
  s->step_ = m.step();
  s->next_agent_id_ = m.next_agent_id();
  s->eos_cache_size_ = m.eos_cache_size();
  for (const state::Agent& p : m.agents()) {
    Agent& a = s->agents_.emplace_back();
    a.id = p.id();
    a.state = get_state(p.state());
    a.kin = {p.kin().x(), p.kin().y(), p.kin().heading(), p.kin_speed()};
    if (p.has_forced()) {
      a.forced = get_state(p.forced());
      if (!finite_state(*a.forced)) return bad(absl::StrCat("agent ", a.id, " has a non-finite forced state"));
    }
    if (p.type() < 0 || p.type() >= kAgentTypes || p.slot() < 0 || p.slot() >= c.agent_slots || p.last_motion() < 0 ||
        p.last_motion() >= kMotionTokens || p.next_motion() < -1 || p.next_motion() >= kMotionVocab ||
        !finite_state(a.state))
      return bad(absl::StrCat("agent ", a.id, " has a field out of range"));
    a.type = p.type();
    a.slot = p.slot();
    a.last_motion = p.last_motion();
    a.next_motion = p.next_motion();
    a.controlled = p.controlled();
    a.entered_step = p.entered_step();
    a.path_s = p.path_s();
    if (!std::isfinite(a.path_s)) return bad(absl::StrCat("agent ", a.id, " has a non-finite path position"));
  }
  for (const state::Light& p : m.lights()) {
    Light& l = s->lights_.emplace_back();
    l.lane = p.lane();
    l.pose = {p.pose().x(), p.pose().y(), p.pose().heading()};
    if (p.map_id() < 0 || p.map_id() >= map->size() || p.state() < 0 || p.state() >= kLightStates ||
        p.next_state() < 0 || p.next_state() >= kLightStates ||
        (p.has_forced() && (p.forced() < 0 || p.forced() >= kLightStates)))
      return bad(absl::StrCat("light on lane ", l.lane, " has a field out of range"));
    l.map_id = p.map_id();
    l.state = static_cast<LightState>(p.state());
    l.next_state = static_cast<LightState>(p.next_state());
    if (p.has_forced()) l.forced = static_cast<LightState>(p.forced());
  }
  if (static_cast<int>(s->lights_.size()) > c.light_slots) return bad("more lights than light slots");
  s->left_.assign(m.left().begin(), m.left().end());
  for (const state::ReleasedSlot& p : m.released_slots()) {
    if (p.slot() < 0 || p.slot() >= c.agent_slots) return bad("released slot out of range");
    s->released_slots_.emplace_back(p.slot(), p.step());
  }
  if (m.slot_used_size() != c.agent_slots) return bad("slot table does not match the model");
  s->slot_used_.assign(m.slot_used().begin(), m.slot_used().end());

  for (const state::Batch& pb : m.replay()) {
    Batch& b = s->replay_.emplace_back();
    b.step = pb.step();
    if (pb.tokens().empty()) return bad(absl::StrCat("the token batch of step ", b.step, " is empty"));
    for (const state::Token& p : pb.tokens()) {
      DecoderToken& t = b.tokens.emplace_back();
      bool ok = p.motion_state_size() == kMotionStateFeatures && p.relative_state_size() == kRsFields;
      if (ok) {
        std::copy(p.motion_state().begin(), p.motion_state().end(), t.motion_state.begin());
        std::copy(p.relative_state().begin(), p.relative_state().end(), t.relative_state.begin());
      }
      t.kind = static_cast<TokenKind>(p.kind());
      t.seq = p.seq();
      t.step = p.step();
      t.object = p.object();
      t.has_pose = p.posed();
      t.pose = {p.pose().x(), p.pose().y(), p.pose().heading()};
      t.agent_slot = p.agent_slot(), t.agent_type = p.agent_type(), t.intra_index = p.intra_index();
      t.light_slot = p.light_slot(), t.light_state = p.light_state(), t.map_id = p.map_id();
      t.motion_action = p.motion_action();
      ok = ok && std::isfinite(t.pose.x) && std::isfinite(t.pose.y) && std::isfinite(t.pose.heading);
      for (float f : t.motion_state) ok = ok && std::isfinite(f);
      for (float f : t.relative_state) ok = ok && std::isfinite(f);
      if (!ok || p.kind() < 0 || p.kind() > static_cast<int32_t>(TokenKind::motion) || t.agent_slot < 0 ||
          t.agent_slot >= c.agent_slots || t.agent_type < 0 || t.agent_type >= kAgentTypes || t.intra_index < 0 ||
          t.intra_index >= 4 * c.agent_slots || t.light_slot < 0 || t.light_slot >= c.light_slots ||
          t.light_state < 0 || t.light_state >= kLightStates || t.map_id < 0 || t.map_id >= map->size() ||
          t.motion_action < 0 || t.motion_action >= kMotionTokens || t.step != b.step)
        return bad(absl::StrCat("a token of step ", b.step, " has a field out of range"));
    }
  }

  // Rebuild the cache by running the batches again, exactly as they first ran.
  s->cache_ = model->new_cache();
  if (!s->replay_.empty()) s->cache_.next_seq = s->replay_.front().tokens.front().seq;
  const int window = s->effective_window();
  for (Batch& b : s->replay_) {
    const int64_t expected = s->cache_.next_seq;
    if (b.tokens.front().seq != expected) return bad("token batches are not contiguous");
    s->cache_.evict_before(b.step - window + 1);
    std::vector<DecoderToken> tokens = b.tokens;
    model->decode(*map, s->cache_, tokens, {});  // only the cache is wanted
  }
  if (s->eos_cache_size_ < 0 || s->eos_cache_size_ > s->cache_.size()) return bad("cache position out of range");
  if (s->rule_mode()) {
    // The plans are not saved: each is a function of the saved states, made again as step() made it.
    auto paths = std::make_shared<std::vector<LoggedPath>>();
    for (const Track& t : scenario->tracks) paths->push_back(logged_path(t));
    s->paths_ = std::move(paths);
    for (const Agent& a : s->agents_)
      if (!a.controlled && s->track_of(a.id) < 0) return bad(absl::StrCat("agent ", a.id, " has no track to follow"));
    s->plan_rule_agents();
  }
  return s;
}

}  // namespace ss
