// Session save and restore. The byte form holds the session's own state (options, RNG, agents, lights) and the
// decoder batches of the last L * (W - 1) steps; restore() re-runs those batches, in the same batches, which
// rebuilds every key and value the cache holds bit for bit (keys at layer l depend on tokens at most l * (W - 1)
// steps older), so a restored session continues exactly as the saved one would have.
#include <cmath>
#include <cstring>
#include <string_view>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "engine/sim/session.h"

namespace ss {
namespace {

// kSessionStateMagic without its terminating NUL.
constexpr std::string_view kMagic(kSessionStateMagic, sizeof kSessionStateMagic - 1);

class Writer {
 public:
  template <typename T>
  void pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void str(const std::string& s) {
    pod<uint64_t>(s.size());
    out_ += s;
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(const std::string& b) : b_(b) {}
  template <typename T>
  bool pod(T& v) {
    if (b_.size() - pos_ < sizeof(T)) return fail();
    std::memcpy(&v, b_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool str(std::string& s) {
    uint64_t n = 0;
    if (!pod(n) || n > b_.size() - pos_) return fail();
    s.assign(b_.data() + pos_, n);
    pos_ += n;
    return true;
  }
  // A count that must fit in the bytes left, at `min_bytes` each (so corrupt counts cannot allocate wildly).
  bool count(uint64_t& n, size_t min_bytes) {
    if (!pod(n) || n > (b_.size() - pos_) / std::max<size_t>(min_bytes, 1)) return fail();
    return true;
  }
  bool ok() const { return ok_; }
  bool at_end() const { return pos_ == b_.size(); }
  size_t pos() const { return pos_; }

 private:
  bool fail() { return ok_ = false; }
  const std::string& b_;
  size_t pos_ = 0;
  bool ok_ = true;
};

void write_state(Writer& w, const StepState& s) {
  for (double v : {s.x, s.y, s.heading, s.vx, s.vy, s.length, s.width, s.height}) w.pod(v);
  w.pod<uint8_t>(s.valid);
}

bool read_state(Reader& r, StepState& s) {
  uint8_t valid = 0;
  bool ok = r.pod(s.x) && r.pod(s.y) && r.pod(s.heading) && r.pod(s.vx) && r.pod(s.vy) && r.pod(s.length) &&
            r.pod(s.width) && r.pod(s.height) && r.pod(valid);
  s.valid = valid;
  return ok;
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
  Writer w;
  w.bytes().append(kMagic);
  w.str(scenario_->id);
  w.pod<int64_t>(map_->size());
  w.pod(map_fingerprint(*map_));
  w.pod<int32_t>(static_cast<int32_t>(options_.mode));
  w.pod(options_.seed);
  w.pod(options_.top_p);
  w.pod(options_.temperature);
  w.pod<int32_t>(options_.max_agents);
  w.pod(options_.roi_radius);
  w.pod<int32_t>(options_.window_steps);
  w.pod<uint64_t>(options_.controlled_ids.size());
  for (int32_t id : options_.controlled_ids) w.pod(id);
  w.pod<int32_t>(options_.densify_target);
  w.pod<uint8_t>(options_.control_sdc);
  w.pod<int32_t>(options_.tick_hz);
  w.pod(tick_);
  for (const auto* poses : {&latest_pose_, &step_controls_}) {
    w.pod<uint64_t>(poses->size());
    for (const auto& [id, c] : *poses) {
      w.pod(c.agent_id);
      for (double v : {c.x, c.y, c.heading}) w.pod(v);
      w.pod<uint8_t>(c.speed.has_value());
      w.pod(c.speed.value_or(0.0));
    }
  }

  w.pod(rng_.s);
  w.pod<int32_t>(step_);
  w.pod(next_agent_id_);
  w.pod<int32_t>(eos_cache_size_);
  w.pod<uint64_t>(agents_.size());
  for (const Agent& a : agents_) {
    w.pod(a.id);
    w.pod<int32_t>(a.type);
    w.pod<int32_t>(a.slot);
    write_state(w, a.state);
    for (double v : {a.kin.x, a.kin.y, a.kin.heading, a.kin.speed}) w.pod(v);
    w.pod<int32_t>(a.last_motion);
    w.pod<int32_t>(a.next_motion);
    w.pod<uint8_t>(a.controlled);
    w.pod<int32_t>(a.entered_step);
    w.pod<uint8_t>(a.forced.has_value());
    if (a.forced) write_state(w, *a.forced);
  }
  w.pod<uint64_t>(lights_.size());
  for (const Light& l : lights_) {
    w.pod(l.lane);
    w.pod<int32_t>(l.map_id);
    for (double v : {l.pose.x, l.pose.y, l.pose.heading}) w.pod(v);
    w.pod<uint8_t>(static_cast<uint8_t>(l.state));
    w.pod<uint8_t>(static_cast<uint8_t>(l.next_state));
    w.pod<int16_t>(l.forced ? static_cast<int16_t>(*l.forced) : -1);
  }
  w.pod<uint64_t>(left_.size());
  for (int64_t id : left_) w.pod(id);
  w.pod<uint64_t>(released_slots_.size());
  for (const auto& [slot, at] : released_slots_) w.pod<int32_t>(slot), w.pod<int32_t>(at);
  w.pod<uint64_t>(slot_used_.size());
  for (bool u : slot_used_) w.pod<uint8_t>(u);

  w.pod<uint64_t>(replay_.size());
  for (const Batch& b : replay_) {
    w.pod<int32_t>(b.step);
    w.pod<uint64_t>(b.tokens.size());
    for (const DecoderToken& t : b.tokens) {
      w.pod<uint8_t>(static_cast<uint8_t>(t.kind));
      w.pod(t.seq);
      w.pod<int32_t>(t.step);
      w.pod(t.object);
      w.pod<uint8_t>(t.has_pose);
      for (double v : {t.pose.x, t.pose.y, t.pose.heading}) w.pod(v);
      for (int32_t v : {t.agent_slot, t.agent_type, t.intra_index, t.light_slot, t.light_state, t.map_id, t.motion_action})
        w.pod(v);
      w.pod(t.motion_state);
      w.pod(t.relative_state);
    }
  }
  return std::move(w.bytes());
}

absl::StatusOr<std::unique_ptr<Session>> Session::restore(std::shared_ptr<const Model> model,
                                                          std::shared_ptr<const Scenario> scenario,
                                                          std::shared_ptr<const MapContext> map,
                                                          const std::string& bytes) {
  auto bad = [](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat("session snapshot: ", what));
  };
  if (bytes.size() < kMagic.size() || bytes.compare(0, kMagic.size() - 1, kMagic.substr(0, kMagic.size() - 1)) != 0)
    return bad("not a session snapshot (bad magic)");
  if (bytes[kMagic.size() - 1] != kMagic.back())
    return absl::FailedPreconditionError(absl::StrCat("session snapshot: state format version ",
                                                      std::string(1, bytes[kMagic.size() - 1]),
                                                      " is not this engine's version ", std::string(1, kMagic.back())));
  const ModelConfig& c = model->config();
  Reader r(bytes);
  char magic[kMagic.size()];
  r.pod(magic);
  auto s = std::unique_ptr<Session>(new Session());
  s->model_ = model;
  s->scenario_ = scenario;
  s->map_ = map;

  std::string scenario_id;
  int64_t map_size = 0;
  uint64_t fingerprint = 0;
  if (!r.str(scenario_id) || !r.pod(map_size) || !r.pod(fingerprint)) return bad("truncated header");
  if (scenario_id != scenario->id)
    return bad(absl::StrCat("saved for scenario ", scenario_id, ", restoring onto ", scenario->id));
  if (map_size != map->size() || fingerprint != map_fingerprint(*map))
    return bad("saved on a different map encoding (segments differ)");
  SessionOptions& o = s->options_;
  int32_t mode = 0;
  uint64_t n = 0;
  if (!r.pod(mode) || !r.pod(o.seed) || !r.pod(o.top_p) || !r.pod(o.temperature) || !r.pod(o.max_agents) ||
      !r.pod(o.roi_radius) || !r.pod(o.window_steps) || !r.count(n, sizeof(int32_t)))
    return bad("truncated options");
  o.mode = static_cast<SessionMode>(mode);
  o.controlled_ids.resize(n);
  for (int32_t& id : o.controlled_ids) r.pod(id);
  r.pod(o.densify_target);
  uint8_t control_sdc = 1;
  r.pod(control_sdc);
  o.control_sdc = control_sdc;
  if (!r.pod(o.tick_hz) || !r.pod(s->tick_)) return bad("truncated tick clock");
  if (o.tick_hz != 2 && o.tick_hz != 10) return bad(absl::StrCat("tick_hz ", o.tick_hz, " (only 2 or 10)"));
  if (s->tick_ < 0) return bad("negative tick");
  for (auto* poses : {&s->latest_pose_, &s->step_controls_}) {
    if (!r.count(n, 41)) return bad("truncated pushed poses");
    for (uint64_t i = 0; i < n; ++i) {
      ControlInput c;
      uint8_t has_speed = 0;
      double speed = 0;
      if (!r.pod(c.agent_id) || !r.pod(c.x) || !r.pod(c.y) || !r.pod(c.heading) || !r.pod(has_speed) ||
          !r.pod(speed))
        return bad("truncated pushed pose");
      if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.heading) || !std::isfinite(speed))
        return bad(absl::StrCat("pushed pose of agent ", c.agent_id, " has a non-finite value"));
      if (has_speed) c.speed = speed;
      (*poses)[c.agent_id] = c;
    }
  }
  if (!r.ok()) return bad("truncated options");
  if (mode < 0 || mode > 2 || !(o.temperature > 0) || !(o.top_p > 0 && o.top_p <= 1) || o.max_agents < 1 ||
      o.max_agents > c.agent_slots || !(o.roi_radius > 0) || o.window_steps < 0 || o.window_steps > c.window_steps)
    return bad("options out of range");

  int32_t step = 0, eos = 0;
  if (!r.pod(s->rng_.s) || !r.pod(step) || !r.pod(s->next_agent_id_) || !r.pod(eos) || !r.count(n, 60))
    return bad("truncated session state");
  s->step_ = step;
  s->eos_cache_size_ = eos;
  s->agents_.resize(n);
  for (Agent& a : s->agents_) {
    uint8_t controlled = 0, has_forced = 0;
    int32_t type = 0, slot = 0, last = 0, next = 0, entered = 0;
    if (!r.pod(a.id) || !r.pod(type) || !r.pod(slot) || !read_state(r, a.state) || !r.pod(a.kin.x) ||
        !r.pod(a.kin.y) || !r.pod(a.kin.heading) || !r.pod(a.kin.speed) || !r.pod(last) || !r.pod(next) ||
        !r.pod(controlled) || !r.pod(entered) || !r.pod(has_forced))
      return bad("truncated agent");
    if (has_forced) {
      a.forced.emplace();
      if (!read_state(r, *a.forced) || !finite_state(*a.forced)) return bad("bad forced state");
    }
    if (type < 0 || type >= kAgentTypes || slot < 0 || slot >= c.agent_slots || last < 0 || last >= kMotionTokens ||
        next < -1 || next >= kMotionVocab || !finite_state(a.state))
      return bad(absl::StrCat("agent ", a.id, " has a field out of range"));
    a.type = type;
    a.slot = slot;
    a.last_motion = last;
    a.next_motion = next;
    a.controlled = controlled;
    a.entered_step = entered;
  }
  if (!r.count(n, 35)) return bad("truncated lights");
  s->lights_.resize(n);
  for (Light& l : s->lights_) {
    int32_t map_id = 0;
    uint8_t state = 0, next = 0;
    int16_t forced = 0;
    if (!r.pod(l.lane) || !r.pod(map_id) || !r.pod(l.pose.x) || !r.pod(l.pose.y) || !r.pod(l.pose.heading) ||
        !r.pod(state) || !r.pod(next) || !r.pod(forced))
      return bad("truncated light");
    if (map_id < 0 || map_id >= map->size() || state >= kLightStates || next >= kLightStates || forced >= kLightStates)
      return bad(absl::StrCat("light on lane ", l.lane, " has a field out of range"));
    l.map_id = map_id;
    l.state = static_cast<LightState>(state);
    l.next_state = static_cast<LightState>(next);
    if (forced >= 0) l.forced = static_cast<LightState>(forced);
  }
  if (static_cast<int>(s->lights_.size()) > c.light_slots) return bad("more lights than light slots");
  if (!r.count(n, 8)) return bad("truncated retired agents");
  s->left_.resize(n);
  for (int64_t& id : s->left_) r.pod(id);
  if (!r.count(n, 8)) return bad("truncated released slots");
  s->released_slots_.resize(n);
  for (auto& [slot, at] : s->released_slots_) {
    int32_t a = 0, b = 0;
    r.pod(a), r.pod(b);
    if (a < 0 || a >= c.agent_slots) return bad("released slot out of range");
    slot = a, at = b;
  }
  if (!r.count(n, 1) || n != static_cast<uint64_t>(c.agent_slots)) return bad("slot table does not match the model");
  s->slot_used_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    uint8_t u = 0;
    r.pod(u);
    s->slot_used_[i] = u;
  }

  if (!r.count(n, 12)) return bad("truncated token batches");
  s->replay_.resize(n);
  for (Batch& b : s->replay_) {
    uint64_t count = 0;
    if (!r.pod(b.step) || !r.count(count, 100) || count == 0) return bad("truncated token batch");
    b.tokens.resize(count);
    for (DecoderToken& t : b.tokens) {
      uint8_t kind = 0, has_pose = 0;
      int32_t step_t = 0, v[7];
      if (!r.pod(kind) || !r.pod(t.seq) || !r.pod(step_t) || !r.pod(t.object) || !r.pod(has_pose) ||
          !r.pod(t.pose.x) || !r.pod(t.pose.y) || !r.pod(t.pose.heading) || !r.pod(v) || !r.pod(t.motion_state) ||
          !r.pod(t.relative_state))
        return bad("truncated token");
      t.kind = static_cast<TokenKind>(kind);
      t.step = step_t;
      t.has_pose = has_pose;
      t.agent_slot = v[0], t.agent_type = v[1], t.intra_index = v[2], t.light_slot = v[3], t.light_state = v[4];
      t.map_id = v[5], t.motion_action = v[6];
      bool finite = std::isfinite(t.pose.x) && std::isfinite(t.pose.y) && std::isfinite(t.pose.heading);
      for (float f : t.motion_state) finite = finite && std::isfinite(f);
      for (float f : t.relative_state) finite = finite && std::isfinite(f);
      if (kind > static_cast<uint8_t>(TokenKind::motion) || t.agent_slot < 0 || t.agent_slot >= c.agent_slots ||
          t.agent_type < 0 || t.agent_type >= kAgentTypes || t.intra_index < 0 || t.intra_index >= 4 * c.agent_slots ||
          t.light_slot < 0 || t.light_slot >= c.light_slots || t.light_state < 0 || t.light_state >= kLightStates ||
          t.map_id < 0 || t.map_id >= map->size() || t.motion_action < 0 || t.motion_action >= kMotionTokens || !finite ||
          t.step != b.step)
        return bad(absl::StrCat("a token of step ", b.step, " has a field out of range"));
    }
  }
  if (!r.at_end()) return bad(absl::StrCat("unexpected bytes after offset ", r.pos()));

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
  return s;
}

}  // namespace ss
