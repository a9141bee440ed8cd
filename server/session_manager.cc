#include "server/session_manager.h"

#include <algorithm>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "server/allocator.h"
#include "server/session_id.h"
#include "server/snapshot.h"
#include "spdlog/spdlog.h"

namespace ss::server {
namespace {

// The one answer for an id the caller cannot see: unknown, closed, or another tenant's.
absl::Status not_found(const std::string& id) {
  return absl::NotFoundError(absl::StrCat("session_id ", echo_id(id), " is not an open session"));
}

}  // namespace

// One hosted session. `engine_mu` serialises engine calls on `session`; `mu` guards the tick clock, the multi-client
// barrier and the recent ticks (held only briefly, never across an engine call).
struct ManagedSession {
  std::string id;
  std::string tenant;                            // the owner (server/auth.h); immutable
  SessionSource source;
  int tick_deadline_ms = 0;

  std::timed_mutex engine_mu;
  SessionPtr session;
  std::atomic<uint64_t> bytes{0};
  uint64_t max_tick_growth = 0;                  // the most one tick has added to `bytes` (under engine_mu)
  std::atomic<uint64_t> changes{1};              // counts ticks, injections and forces (1: never saved)
  uint64_t saved_changes = 0;                    // `changes` when the snapshot was last written (under engine_mu)
  std::atomic<int64_t> last_used{0};             // steady clock, nanoseconds
  std::atomic<int> calls{0};                     // calls in progress: waiting (a slot, other controllers) or running

  std::mutex mu;
  std::condition_variable cv;
  int64_t tick = 0;
  StepResult view;                               // the current tick as GetSession shows it (no events)
  std::set<int64_t> controllers;                 // controlled agents alive: each may have its own client
  std::map<int64_t, std::string> controller_of;  // agent -> its controller's credential (JoinSession)
  std::map<int64_t, ControlInput> pending;       // poses for tick + 1
  std::optional<Clock::time_point> pending_since;
  bool stepping = false;
  int64_t failed_tick = -1;
  absl::Status failed_status;
  std::deque<TickView> recent;                   // the last ticks, for waiting controllers
  std::vector<std::shared_ptr<TickWatcher>> watchers;  // WatchSession streams
  bool closed = false;

  void touch() { last_used = Clock::now().time_since_epoch().count(); }
  // 0 while a call is in progress: a call that waits (for a compute thread under load, or for the other controllers
  // of a multi-client tick) must not have its session closed or evicted under it by the idle rules.
  double idle_seconds() const {
    if (calls > 0) return 0;
    return std::chrono::duration<double>(Clock::now().time_since_epoch() - Clock::duration(last_used.load())).count();
  }
  // Holds mu.
  void publish(const StepResult& v) {
    view = v;
    view.events.clear();  // events belong to the tick a call made (StepScene, watchers), not to the current view
    controllers.clear();
    for (const AgentView& a : v.agents)
      if (a.controlled) controllers.insert(a.id);
    recent.push_back({tick, v});
    while (recent.size() > 64) recent.pop_front();
    std::erase_if(watchers, [](const auto& w) { return w->done(); });
    for (const auto& w : watchers) w->on_tick(recent.back());
  }
};

// A call in progress on a session (ManagedSession::calls) for as long as it lives; the session counts as used when
// the call ends.
struct InCall {
  explicit InCall(ManagedSession& m) : s(m) { ++s.calls; }
  ~InCall() {
    s.touch();
    --s.calls;
  }
  ManagedSession& s;
};

SessionManager::SessionManager(Engine& engine, ManagerOptions options, Metrics& metrics)
    : engine_(engine),
      options_(std::move(options)),
      metrics_(metrics),
      compute_(std::max(1, options_.compute_threads), engine_thread_init) {
  reaper_ = std::thread([this] { reaper(); });
}

SessionManager::~SessionManager() {
  stop_ = true;
  if (reaper_.joinable()) reaper_.join();
}

absl::Status SessionManager::compute(Clock::time_point deadline, const std::function<absl::Status()>& fn) {
  return compute_.run(deadline, fn);
}

int SessionManager::count() {
  std::lock_guard<std::mutex> l(mu_);
  return static_cast<int>(sessions_.size());
}

uint64_t SessionManager::total_bytes() {
  std::lock_guard<std::mutex> l(mu_);
  uint64_t b = 0;
  for (const auto& [id, s] : sessions_) b += s->bytes;
  return b;
}

absl::StatusOr<std::string> SessionManager::new_id(const std::string& proposed) {
  if (proposed.empty()) return random_session_id();
  if (auto st = check_session_id(proposed); !st.ok()) return st;
  if (sessions_.count(proposed) || evicted_.count(proposed))
    return absl::AlreadyExistsError(absl::StrCat("session_id ", echo_id(proposed), " is already in use"));
  return proposed;
}

absl::Status SessionManager::save(ManagedSession& s) {
  Snapshot snap;
  snap.session_id = s.id;
  snap.source = s.source;
  snap.tick_deadline_ms = s.tick_deadline_ms;
  snap.tenant = s.tenant;
  {
    std::lock_guard<std::mutex> l(s.mu);
    snap.controllers.assign(s.controller_of.begin(), s.controller_of.end());
  }
  snap.session_bytes = session_save(*s.session);
  const uint64_t changes = s.changes;
  absl::Status st = write_snapshot(options_.snapshot_dir, snap);
  if (st.ok()) s.saved_changes = changes;
  return st;
}

absl::Status SessionManager::evict_locked(const std::shared_ptr<ManagedSession>& s) {
  std::unique_lock<std::timed_mutex> e(s->engine_mu, std::try_to_lock);
  if (!e.owns_lock()) return absl::AbortedError("busy");
  if (!options_.snapshot_dir.empty()) {
    if (auto st = save(*s); !st.ok()) return st;
    evicted_[s->id] = s->tenant;
  }
  {
    std::lock_guard<std::mutex> l(s->mu);
    s->closed = true;
    s->cv.notify_all();
    end_watchers_locked(*s);
  }
  sessions_.erase(s->id);
  ++closed_since_trim_;
  metrics_.count_eviction();
  spdlog::info("session {}: evicted after {:.1f} s idle{}", s->id, s->idle_seconds(),
               options_.snapshot_dir.empty() ? " (no snapshot directory: dropped)" : ", snapshot saved");
  return absl::OkStatus();
}

absl::Status SessionManager::make_room_locked(uint64_t extra_bytes, int extra_sessions, const ManagedSession* keep) {
  auto held = [&] {
    uint64_t b = 0;
    for (const auto& [id, s] : sessions_) b += s->bytes;
    return b;
  };
  auto over = [&] {
    return static_cast<int>(sessions_.size()) + extra_sessions > options_.max_sessions ||
           held() + extra_bytes > options_.max_cache_bytes;
  };
  while (over()) {
    std::vector<std::shared_ptr<ManagedSession>> idle;
    for (const auto& [id, s] : sessions_)
      if (s.get() != keep && s->calls == 0 && s->idle_seconds() >= options_.evict_idle_s) idle.push_back(s);
    std::sort(idle.begin(), idle.end(), [](const auto& a, const auto& b) { return a->last_used < b->last_used; });
    bool evicted = false;
    for (const auto& s : idle)
      if (evict_locked(s).ok()) {
        evicted = true;
        break;
      }
    if (!evicted)
      return absl::ResourceExhaustedError(absl::StrCat(
          std::to_string(sessions_.size()), " sessions holding ", std::to_string(held()), " bytes, ",
          std::to_string(extra_bytes), " more bytes needed: the caps are --max_sessions=",
          std::to_string(options_.max_sessions), " and --max_cache_mb=", std::to_string(options_.max_cache_bytes >> 20),
          ", and no other session has been idle for --evict_idle_s=", std::to_string(options_.evict_idle_s),
          " s to be evicted"));
  }
  return absl::OkStatus();
}

absl::StatusOr<TickView> SessionManager::create(const std::string& tenant, const SessionSource& source,
                                                const SessionOptions& options, int tick_deadline_ms,
                                                const std::string& proposed_id, Clock::time_point deadline,
                                                std::string* id_out, std::vector<MapFeature>* map) {
  if (draining_) return absl::UnavailableError("the server is draining (shutting down): no new sessions");
  if (tick_deadline_ms < 0) return absl::InvalidArgumentError("tick_deadline_ms must not be negative");
  std::string id;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto nid = new_id(proposed_id);
    if (!nid.ok()) return nid.status();
    id = *nid;
    if (auto st = make_room_locked(0); !st.ok()) return st;
  }
  auto s = std::make_shared<ManagedSession>();
  s->id = id;
  s->tenant = tenant;
  s->source = source;
  s->tick_deadline_ms = tick_deadline_ms ? tick_deadline_ms : options_.default_tick_deadline_ms;
  absl::Status st = compute(deadline, [&] {
    auto session = session_create(engine_, source, options);
    if (!session.ok()) return session.status();
    s->session = std::move(*session);
    s->bytes = session_memory_bytes(engine_, *s->session) + source.womd_bytes.size();
    return absl::OkStatus();
  });
  if (!st.ok()) return st;
  s->touch();
  TickView out;
  {
    std::lock_guard<std::mutex> l(s->mu);
    s->publish(session_view(*s->session));
    out = s->recent.back();
  }
  // Copied before the session is listed: from then on another call may close it.
  if (map) *map = session_map_features(*s->session);
  {
    std::lock_guard<std::mutex> l(mu_);
    if (draining_) return absl::UnavailableError("the server is draining (shutting down): no new sessions");
    if (sessions_.count(id)) return absl::AlreadyExistsError(absl::StrCat("session_id '", id, "' is already in use"));
    if (auto st2 = make_room_locked(s->bytes); !st2.ok()) return st2;
    sessions_[id] = s;
  }
  spdlog::info("session {}: created on {} ({} mode, seed {}, {} Hz, {} agents, {} bytes)", id,
               source.scenario_name.empty() ? std::string("client-sent scenario") : source.scenario_name,
               session_mode_name(options.mode), options.seed, options.tick_hz, out.view.agents.size(), s->bytes.load());
  *id_out = id;
  return out;
}

absl::StatusOr<std::shared_ptr<ManagedSession>> SessionManager::find(const std::string& id, const std::string& tenant,
                                                                     Clock::time_point deadline) {
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) {
      if (it->second->tenant != tenant) return not_found(id);  // not touched either: it is not the caller's
      it->second->touch();
      return it->second;
    }
    auto ev = evicted_.find(id);
    if (ev == evicted_.end() || ev->second != tenant) return not_found(id);
    if (draining_) return absl::UnavailableError("the server is draining: evicted sessions are not restored now");
  }
  // Evicted earlier: bring it back from its snapshot.
  auto s = restore_snapshot(id, deadline);
  if (!s.ok()) return s.status();
  std::lock_guard<std::mutex> l(mu_);
  auto it = sessions_.find(id);
  if (it != sessions_.end()) {  // another call restored it first
    if (it->second->tenant != tenant) return not_found(id);
    return it->second;
  }
  if ((*s)->tenant != tenant) return not_found(id);  // the snapshot says otherwise than evicted_ did
  // A CloseSession while the snapshot was being read won: the session stays closed.
  if (!evicted_.count(id))
    return absl::NotFoundError(absl::StrCat("session_id ", echo_id(id), " was closed while it was being restored"));
  if (auto st = make_room_locked((*s)->bytes); !st.ok()) return st;
  evicted_.erase(id);
  sessions_[id] = *s;
  // The snapshot stays until the session closes: a crash before the next save still finds it.
  spdlog::info("session {}: restored from its eviction snapshot at tick {}", id, (*s)->tick);
  return *s;
}

absl::StatusOr<std::shared_ptr<ManagedSession>> SessionManager::restore_snapshot(const std::string& id,
                                                                                 Clock::time_point deadline) {
  auto snap = read_snapshot(options_.snapshot_dir, id);
  if (!snap.ok()) return snap.status();
  return restore_from(std::move(*snap), deadline);
}

absl::StatusOr<std::shared_ptr<ManagedSession>> SessionManager::restore_from(Snapshot snap,
                                                                             Clock::time_point deadline) {
  const std::string path = *snapshot_path(options_.snapshot_dir, snap.session_id);
  auto s = std::make_shared<ManagedSession>();
  s->id = snap.session_id;
  s->tenant = snap.tenant;
  s->source = snap.source;
  s->tick_deadline_ms = snap.tick_deadline_ms;
  absl::Status st = compute(deadline, [&] {
    auto session = session_restore(engine_, snap.source, snap.session_bytes);
    if (!session.ok()) return session.status();
    s->session = std::move(*session);
    s->bytes = session_memory_bytes(engine_, *s->session) + s->source.womd_bytes.size();
    return absl::OkStatus();
  });
  if (!st.ok()) return absl::Status(st.code(), absl::StrCat("snapshot ", path, ": ", std::string(st.message())));
  s->touch();
  s->saved_changes = s->changes;  // its snapshot is on disk already
  std::lock_guard<std::mutex> l(s->mu);
  s->tick = session_tick_index(*s->session);
  s->controller_of.insert(snap.controllers.begin(), snap.controllers.end());
  s->publish(session_view(*s->session));
  return s;
}

absl::Status SessionManager::run_ticks(ManagedSession& s, const std::vector<ControlInput>& controls, int n,
                                       Clock::time_point deadline, const std::function<bool()>& cancelled,
                                       std::vector<TickView>* out) {
  int64_t tick;
  {
    std::lock_guard<std::mutex> l(s.mu);
    tick = s.tick;
  }
  const std::vector<ControlInput> none;
  for (int i = 0; i < n; ++i) {
    // The poses are for the first tick; later ticks of the call keep the controlled agents' last control.
    const std::vector<ControlInput>& controls_now = i == 0 ? controls : none;
    // Between the ticks of a long call: a client that is gone or out of time gets no more (a slot free at once
    // would otherwise keep computing ticks no one reads). The first tick always runs: in a multi-client session it
    // is every controller's tick, not only this caller's.
    if (i > 0 && (Clock::now() >= deadline || (cancelled && cancelled()))) {
      const bool late = Clock::now() >= deadline;
      return absl::Status(late ? absl::StatusCode::kDeadlineExceeded : absl::StatusCode::kCancelled,
                          absl::StrCat(late ? "the call's deadline passed" : "the client cancelled the call",
                                       " after ", std::to_string(i), " of ", std::to_string(n),
                                       " ticks; the session is at tick ", std::to_string(tick)));
    }
    // The cache cap holds as sessions grow: room for the largest growth of one tick seen so far, before the tick.
    if (auto st = room_to_grow(s); !st.ok()) {
      if (i == 0) return st;
      return absl::Status(st.code(), absl::StrCat(st.message(), " (after ", std::to_string(i), " of ",
                                                  std::to_string(n), " ticks; the session is at tick ",
                                                  std::to_string(tick), ")"));
    }
    StepResult view;
    // A compute call per tick, not one for the whole request: a long request queues again between its ticks, so a
    // short request on another session waits for one tick rather than for all of them.
    absl::Status st = compute(deadline, [&]() -> absl::Status {
      const auto t0 = Clock::now();
      auto r = session_tick(*s.session, controls_now);
      if (!r.ok()) return r.status();
      view = std::move(*r);
      metrics_.count_step(std::chrono::duration<double>(Clock::now() - t0).count());
      return absl::OkStatus();
    });
    if (!st.ok()) {
      if (i == 0 || st.code() != absl::StatusCode::kDeadlineExceeded) return st;
      return absl::Status(st.code(), absl::StrCat(st.message(), " (after ", std::to_string(i), " of ",
                                                  std::to_string(n), " ticks; the session is at tick ",
                                                  std::to_string(tick), ")"));
    }
    tick = session_tick_index(*s.session);
    ++s.changes;
    const uint64_t before = s.bytes;
    s.bytes = session_memory_bytes(engine_, *s.session) + s.source.womd_bytes.size();
    if (s.bytes > before) s.max_tick_growth = std::max(s.max_tick_growth, s.bytes - before);
    s.touch();  // a long call keeps its session in use: the idle rule must not close it between two ticks
    std::lock_guard<std::mutex> l(s.mu);
    s.tick = tick;
    s.publish(view);
    out->push_back(s.recent.back());
    s.cv.notify_all();
  }
  return absl::OkStatus();
}

absl::Status SessionManager::room_to_grow(ManagedSession& s) {
  std::lock_guard<std::mutex> l(mu_);
  absl::Status st = make_room_locked(s.max_tick_growth, 0, &s);
  if (st.ok()) return st;
  return absl::ResourceExhaustedError(absl::StrCat(
      "session '", s.id, "' (", std::to_string(s.bytes.load()), " bytes, up to ", std::to_string(s.max_tick_growth),
      " more a tick) has no room to grow: ", st.message()));
}

absl::StatusOr<std::vector<TickView>> SessionManager::step(const std::string& id, const std::string& tenant,
                                                           const std::string& credential,
                                                           const std::vector<ControlInput>& controls, int num_ticks,
                                                           Clock::time_point deadline,
                                                           const std::function<bool()>& cancelled) {
  if (draining_)
    return absl::UnavailableError("the server is draining (shutting down): the session is saved; retry after restart");
  auto found = find(id, tenant, deadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  InCall in_call(s);
  if (num_ticks == 0) num_ticks = 1;
  if (num_ticks < 0 || num_ticks > 1000)
    return absl::InvalidArgumentError(absl::StrCat("num_ticks ", std::to_string(num_ticks), ": must be in 1..1000"));
  std::unique_lock<std::mutex> l(s.mu);
  if (s.closed) return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(id), " was closed"));
  for (size_t i = 0; i < controls.size(); ++i)
    if (!s.controllers.count(controls[i].agent_id))
      return absl::InvalidArgumentError(absl::StrCat("poses[", std::to_string(i), "].agent_id ",
                                                     std::to_string(controls[i].agent_id),
                                                     " is not a controlled agent of session '", id, "'"));
  if (auto st = check_controller_locked(s, credential, controls, "poses", "send its poses"); !st.ok()) return st;
  if (num_ticks > 1 && s.controllers.size() > 1)
    return absl::InvalidArgumentError("num_ticks > 1 is only for sessions with at most one controlled agent");
  if (s.stepping)
    return absl::AbortedError(absl::StrCat("session '", id, "' is computing tick ", std::to_string(s.tick + 1),
                                           ": calls on one session are serialised; retry after it returns"));
  for (const ControlInput& c : controls)
    if (s.pending.count(c.agent_id))
      return absl::AbortedError(absl::StrCat("agent ", std::to_string(c.agent_id), " already sent its pose for tick ",
                                             std::to_string(s.tick + 1), " of session '", id, "'"));
  if (!s.pending_since) {
    // A new attempt at the next tick: an earlier failed attempt's error is not this one's.
    s.failed_tick = -1;
    s.pending_since = Clock::now();
  }
  for (const ControlInput& c : controls) s.pending[c.agent_id] = c;
  const int64_t target = s.tick + 1;
  std::vector<TickView> out;  // the ticks this call computed (all of them, however many it asked for)
  while (s.tick < target) {
    if (s.closed) return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(id), " was closed"));
    if (s.failed_tick == target) return s.failed_status;
    // With one controller (or none) the caller is the only client: its call is the tick. With several, the tick
    // waits for every controller's pose or the session's tick deadline.
    bool all = true;
    if (s.controllers.size() > 1)
      for (int64_t c : s.controllers) all = all && s.pending.count(c);
    const Clock::time_point tick_deadline =
        *s.pending_since + std::chrono::milliseconds(s.tick_deadline_ms);
    if (!s.stepping && (all || Clock::now() >= tick_deadline)) {
      s.stepping = true;
      std::vector<ControlInput> taken;
      for (const auto& [aid, c] : s.pending) taken.push_back(c);
      s.pending.clear();
      s.pending_since.reset();
      l.unlock();
      absl::Status st;
      {
        std::unique_lock<std::timed_mutex> e(s.engine_mu, std::defer_lock);
        if (!e.try_lock_until(deadline))
          st = absl::DeadlineExceededError("the call's deadline passed while the session was busy");
        else
          st = run_ticks(s, taken, num_ticks, deadline, cancelled, &out);
      }
      l.lock();
      s.stepping = false;
      if (!st.ok()) {
        s.failed_tick = target;
        s.failed_status = st;
        s.cv.notify_all();
        spdlog::warn("session {}: tick {} failed: {}", id, target, std::string(st.message()));
        return st;
      }
      s.cv.notify_all();
      break;
    }
    const Clock::time_point until = std::min(tick_deadline, deadline);
    if (Clock::now() >= deadline) {
      for (const ControlInput& c : controls) s.pending.erase(c.agent_id);
      return absl::DeadlineExceededError(absl::StrCat("the call's deadline passed waiting for the other controllers "
                                                      "of session '", id, "'"));
    }
    s.cv.wait_until(l, s.stepping ? deadline : until);
  }
  if (out.empty())  // another controller's call computed the tick (multi-client calls ask for one tick)
    for (const TickView& t : s.recent)
      if (t.tick == target) out.push_back(t);
  s.touch();
  return out;
}

absl::StatusOr<std::vector<int64_t>> SessionManager::inject(const std::string& id, const std::string& tenant,
                                                            const InjectRequest& r, Clock::time_point deadline) {
  if (draining_)
    return absl::UnavailableError("the server is draining (shutting down): the session is saved; retry after restart");
  auto found = find(id, tenant, deadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  InCall in_call(s);
  std::unique_lock<std::timed_mutex> e(s.engine_mu, std::try_to_lock);
  if (!e.owns_lock())
    return absl::AbortedError(absl::StrCat("session '", id, "' is busy with another call; calls are serialised"));
  std::vector<int64_t> ids;
  absl::Status st = compute(deadline, [&] {
    auto r2 = session_inject(*s.session, r);
    if (!r2.ok()) return r2.status();
    ++s.changes;
    ids = *r2;
    s.bytes = session_memory_bytes(engine_, *s.session) + s.source.womd_bytes.size();
    return absl::OkStatus();
  });
  if (!st.ok()) return st;
  std::lock_guard<std::mutex> l(s.mu);
  s.view = session_view(*s.session);
  return ids;
}

absl::Status SessionManager::state_force(const std::string& id, const std::string& tenant,
                                         const std::string& credential, const StateForceRequest& r) {
  if (draining_)
    return absl::UnavailableError("the server is draining (shutting down): the session is saved; retry after restart");
  auto found = find(id, tenant, Clock::now() + std::chrono::seconds(30));
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  InCall in_call(s);
  {
    std::vector<ControlInput> forced;
    for (const auto& [agent, state] : r.agents) {
      ControlInput c;
      c.agent_id = agent;
      forced.push_back(c);
    }
    std::lock_guard<std::mutex> l(s.mu);
    if (auto st = check_controller_locked(s, credential, forced, "agents", "force it"); !st.ok()) return st;
  }
  std::unique_lock<std::timed_mutex> e(s.engine_mu, std::try_to_lock);
  if (!e.owns_lock())
    return absl::AbortedError(absl::StrCat("session '", id, "' is busy with another call; calls are serialised"));
  absl::Status st = session_force(*s.session, r);
  if (st.ok()) ++s.changes;
  return st;
}

absl::Status SessionManager::close(const std::string& id, const std::string& tenant) { return close_impl(id, &tenant); }

absl::Status SessionManager::close_impl(const std::string& id, const std::string* tenant) {
  std::shared_ptr<ManagedSession> s;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(id);
    if (it == sessions_.end()) {
      auto ev = evicted_.find(id);
      if (ev != evicted_.end() && (tenant == nullptr || ev->second == *tenant)) {
        evicted_.erase(ev);
        remove_snapshot(options_.snapshot_dir, id);
        spdlog::info("session {}: closed (was evicted)", id);
        return absl::OkStatus();
      }
      return not_found(id);
    }
    if (tenant != nullptr && it->second->tenant != *tenant) return not_found(id);
    s = it->second;
    sessions_.erase(it);
  }
  {
    std::lock_guard<std::mutex> l(s->mu);
    s->closed = true;
    s->cv.notify_all();
    end_watchers_locked(*s);
    spdlog::info("session {}: closed at tick {}", id, s->tick);
  }
  // A background save running now checks `closed` after writing and removes its file too.
  if (!options_.snapshot_dir.empty()) remove_snapshot(options_.snapshot_dir, id);
  s.reset();  // freed now unless a call still holds it: then the reaper's trim after a later close takes it
  ++closed_since_trim_;
  return absl::OkStatus();
}

static SessionInfo info_of(ManagedSession& s) {
  SessionInfo i;
  i.id = s.id;
  i.scenario_name = s.source.scenario_name;
  i.options = session_options(*s.session);  // immutable after create
  i.tick_hz = i.options.tick_hz;
  i.memory_bytes = s.bytes;
  i.idle_seconds = s.idle_seconds();
  std::lock_guard<std::mutex> l(s.mu);
  i.tick = s.tick;
  i.step = s.view.step;
  i.num_agents = static_cast<int>(s.view.agents.size());
  i.controlled.assign(s.controllers.begin(), s.controllers.end());
  return i;
}

absl::StatusOr<std::pair<SessionInfo, TickView>> SessionManager::get(const std::string& id,
                                                                     const std::string& tenant) {
  auto found = find(id, tenant, Clock::now() + std::chrono::seconds(30));
  if (!found.ok()) return found.status();
  SessionInfo info = info_of(**found);
  std::lock_guard<std::mutex> l((*found)->mu);
  return std::make_pair(info, TickView{(*found)->tick, (*found)->view});
}

std::vector<SessionInfo> SessionManager::list(const std::string& tenant) {
  std::vector<std::shared_ptr<ManagedSession>> all;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, s] : sessions_)
      if (s->tenant == tenant) all.push_back(s);
  }
  std::vector<SessionInfo> out;
  for (const auto& s : all) out.push_back(info_of(*s));
  return out;
}

absl::StatusOr<std::string> SessionManager::fork(const std::string& id, const std::string& tenant,
                                                 const std::string& proposed_id, Clock::time_point deadline) {
  if (draining_) return absl::UnavailableError("the server is draining (shutting down): no new sessions");
  auto found = find(id, tenant, deadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  std::string nid;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto n = new_id(proposed_id);
    if (!n.ok()) return n.status();
    nid = *n;
    if (auto st = make_room_locked(s.bytes); !st.ok()) return st;
  }
  auto f = std::make_shared<ManagedSession>();
  f->id = nid;
  f->tenant = tenant;
  f->source = s.source;
  f->tick_deadline_ms = s.tick_deadline_ms;
  {
    std::unique_lock<std::timed_mutex> e(s.engine_mu, std::defer_lock);
    if (!e.try_lock_until(deadline)) return absl::DeadlineExceededError("the session stayed busy past the deadline");
    absl::Status st = compute(deadline, [&] {
      f->session = session_fork(*s.session);
      return absl::OkStatus();
    });
    if (!st.ok()) return st;
    f->bytes = s.bytes.load();
    std::lock_guard<std::mutex> l(s.mu);
    f->tick = s.tick;
    f->publish(s.view);
  }
  f->touch();
  {
    std::lock_guard<std::mutex> l(mu_);
    if (sessions_.count(nid)) return absl::AlreadyExistsError(absl::StrCat("session_id '", nid, "' is in use"));
    // Again at insert: other forks may have filled the room while this one waited for its busy source.
    if (auto st = make_room_locked(f->bytes); !st.ok()) return st;
    sessions_[nid] = f;
  }
  spdlog::info("session {}: forked from {} at tick {}", nid, id, f->tick);
  return nid;
}

absl::Status SessionManager::check_controller_locked(const ManagedSession& s, const std::string& credential,
                                                    const std::vector<ControlInput>& agents, const char* field,
                                                    const char* action) {
  if (!credential.empty()) {
    bool issued = false;
    for (const auto& [agent, c] : s.controller_of) issued = issued || c == credential;
    if (!issued)
      return absl::PermissionDeniedError(absl::StrCat("controller_credential is not one that session '", s.id,
                                                      "' issued (JoinSession gives one)"));
  }
  for (size_t i = 0; i < agents.size(); ++i) {
    auto it = s.controller_of.find(agents[i].agent_id);
    if (it != s.controller_of.end() && it->second != credential)
      return absl::PermissionDeniedError(absl::StrCat(
          field, "[", std::to_string(i), "]: agent ", std::to_string(agents[i].agent_id), " of session '", s.id,
          "' has a controller: only the client that joined as its controller (JoinSession) may ", action,
          credential.empty() ? " (this call sent no controller_credential)"
                             : " (this call's credential is another client's)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<JoinResult> SessionManager::join(const std::string& id, const std::string& tenant,
                                                const std::vector<int64_t>& agent_ids,
                                                const std::string& credential) {
  if (draining_)
    return absl::UnavailableError("the server is draining (shutting down): the session is saved; retry after restart");
  auto found = find(id, tenant, Clock::now() + std::chrono::seconds(30));
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  if (agent_ids.empty()) return absl::InvalidArgumentError("agent_ids is empty: name the agents to control");
  std::lock_guard<std::mutex> l(s.mu);
  if (s.closed) return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(id), " was closed"));
  if (auto st = check_controller_locked(s, credential, {}, "agent_ids", "join"); !st.ok()) return st;
  std::set<int64_t> seen;
  for (size_t i = 0; i < agent_ids.size(); ++i) {
    const int64_t a = agent_ids[i];
    const std::string where = absl::StrCat("agent_ids[", std::to_string(i), "] ", std::to_string(a));
    if (!s.controllers.count(a))
      return absl::InvalidArgumentError(absl::StrCat(where, " is not a controlled agent of session '", id, "'"));
    if (!seen.insert(a).second) return absl::InvalidArgumentError(absl::StrCat(where, " appears twice"));
    auto it = s.controller_of.find(a);
    if (it != s.controller_of.end() && it->second != credential)
      return absl::AlreadyExistsError(
          absl::StrCat(where, " of session '", id, "' already has a controller (another client joined for it)"));
  }
  JoinResult out;
  out.credential = credential.empty() ? random_session_id() : credential;
  for (int64_t a : agent_ids) s.controller_of[a] = out.credential;
  for (const auto& [agent, c] : s.controller_of)
    if (c == out.credential) out.agents.push_back(agent);
  ++s.changes;  // the claims are saved with the session
  spdlog::info("session {}: a client joined as the controller of {} agents", id, agent_ids.size());
  return out;
}

absl::Status SessionManager::watch_add(const std::string& id, const std::string& tenant,
                                       std::shared_ptr<TickWatcher> w) {
  if (draining_) return absl::UnavailableError("the server is draining (shutting down): no new watch streams");
  auto found = find(id, tenant, Clock::now() + std::chrono::seconds(30));
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  if (++watchers_ > options_.max_watchers) {
    --watchers_;
    return absl::ResourceExhaustedError(absl::StrCat("--max_watchers=", std::to_string(options_.max_watchers),
                                                     " watch streams are open: close one first"));
  }
  std::lock_guard<std::mutex> l(s.mu);
  if (s.closed) {
    --watchers_;
    return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(id), " was closed"));
  }
  s.watchers.push_back(w);
  w->on_tick({s.tick, s.view});
  return absl::OkStatus();
}

void SessionManager::start_draining() {
  draining_ = true;
  std::lock_guard<std::mutex> l(mu_);
  for (const auto& [id, s] : sessions_) {
    std::lock_guard<std::mutex> sl(s->mu);
    end_watchers_locked(*s);
  }
}

void SessionManager::end_watchers_locked(ManagedSession& s) {
  for (const auto& w : s.watchers) w->on_end();
  s.watchers.clear();
}

int SessionManager::save_all() {
  if (options_.snapshot_dir.empty()) return 0;
  std::vector<std::shared_ptr<ManagedSession>> all;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, s] : sessions_) all.push_back(s);
  }
  int saved = 0;
  for (const auto& s : all) {
    std::lock_guard<std::timed_mutex> e(s->engine_mu);
    if (auto st = save(*s); !st.ok()) {
      spdlog::error("session {}: snapshot failed: {}", s->id, std::string(st.message()));
      continue;
    }
    ++saved;
  }
  return saved;
}

int SessionManager::restore_all() {
  if (options_.snapshot_dir.empty()) return 0;
  int n = 0;
  for (const std::string& id : list_snapshots(options_.snapshot_dir)) {
    if (auto st = check_session_id(id); !st.ok()) {
      spdlog::error("snapshot {}: not restored: the file name is not a session id: {}", echo_id(id),
                    std::string(st.message()));
      continue;
    }
    // Read first: its owner decides who may bring it back.
    auto snap = read_snapshot(options_.snapshot_dir, id);
    if (!snap.ok()) {
      spdlog::error("session {}: not restored: {}", id, std::string(snap.status().message()));
      continue;
    }
    const std::string tenant = snap->tenant;
    // The caps hold on a restart too: sessions beyond them stay evicted and come back on their next call.
    {
      std::lock_guard<std::mutex> l(mu_);
      if (static_cast<int>(sessions_.size()) >= options_.max_sessions) {
        evicted_[id] = tenant;
        spdlog::info("session {}: left evicted (--max_sessions={} reached); restored on its next call", id,
                     options_.max_sessions);
        continue;
      }
    }
    auto s = restore_from(std::move(*snap), Clock::now() + std::chrono::minutes(10));
    if (!s.ok()) {
      spdlog::error("session {}: not restored: {}", id, std::string(s.status().message()));
      continue;
    }
    {
      std::lock_guard<std::mutex> l(mu_);
      uint64_t held = (*s)->bytes;
      for (const auto& [other, o] : sessions_) held += o->bytes;
      if (held > options_.max_cache_bytes) {
        evicted_[id] = tenant;
        spdlog::info("session {}: left evicted ({} bytes would pass --max_cache_mb={}); restored on its next call",
                     id, (*s)->bytes.load(), options_.max_cache_bytes >> 20);
        continue;
      }
      sessions_[id] = *s;
    }
    spdlog::info("session {}: restored at tick {}", id, (*s)->tick);
    ++n;
  }
  return n;
}

void SessionManager::save_changed() {
  std::vector<std::shared_ptr<ManagedSession>> all;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, s] : sessions_) all.push_back(s);
  }
  int saved = 0;
  for (const auto& s : all) {
    if (stop_ || draining_) return;
    // A session busy in an engine call is saved at the next interval.
    std::unique_lock<std::timed_mutex> e(s->engine_mu, std::try_to_lock);
    if (!e.owns_lock() || s->changes == s->saved_changes) continue;
    absl::Status st = compute(Clock::now() + std::chrono::seconds(10), [&] { return save(*s); });
    if (!st.ok()) {
      spdlog::warn("session {}: background snapshot failed: {}", s->id, std::string(st.message()));
      continue;
    }
    ++saved;
    bool closed;
    {
      std::lock_guard<std::mutex> l(s->mu);
      closed = s->closed;
    }
    if (closed && !evicted_contains(s->id)) remove_snapshot(options_.snapshot_dir, s->id);
  }
  if (saved) spdlog::debug("background snapshots: {} sessions saved", saved);
}

bool SessionManager::evicted_contains(const std::string& id) {
  std::lock_guard<std::mutex> l(mu_);
  return evicted_.count(id) > 0;
}

void SessionManager::reaper() {
  auto last_save = Clock::now();
  auto last_trim = Clock::now();
  while (!stop_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    // Give what closed sessions freed back to the kernel now (docs/performance.md; server/allocator.h), rather than when
    // jemalloc's decay gets to it: an idle arena's dirty pages decay only when it allocates again.
    if (options_.malloc_trim_interval_s > 0 && closed_since_trim_ > 0 &&
        Clock::now() - last_trim >= std::chrono::duration<double>(options_.malloc_trim_interval_s)) {
      const int closed = closed_since_trim_.exchange(0);
      const auto t0 = Clock::now();
      const int64_t released = allocator_trim();
      last_trim = Clock::now();
      metrics_.count_malloc_trim();
      spdlog::debug("allocator purge after {} sessions closed: RSS {:+.1f} MB in {:.1f} ms", closed,
                    -static_cast<double>(released) / (1 << 20),
                    std::chrono::duration<double, std::milli>(last_trim - t0).count());
    }
    if (!options_.snapshot_dir.empty() && options_.snapshot_interval_s > 0 &&
        Clock::now() - last_save >= std::chrono::duration<double>(options_.snapshot_interval_s)) {
      save_changed();
      last_save = Clock::now();
    }
    std::vector<std::string> expired;
    {
      std::lock_guard<std::mutex> l(mu_);
      for (const auto& [id, s] : sessions_)
        if (s->idle_seconds() > options_.idle_timeout_s) expired.push_back(id);
    }
    for (const std::string& id : expired) {
      spdlog::info("session {}: idle for more than --idle_timeout_s={}, closing", id, options_.idle_timeout_s);
      (void)close_impl(id, nullptr);
    }
  }
}

}  // namespace ss::server
