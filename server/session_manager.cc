#include "server/session_manager.h"

#include <algorithm>
#include <set>

#include "absl/strings/str_cat.h"
#include "server/auth.h"
#include "server/session_id.h"
#include "server/tick_barrier.h"
#include "spdlog/spdlog.h"

namespace ss::server {
namespace {

absl::Status draining_error() {
  return absl::UnavailableError(
      "the server is draining (shutting down): the session is saved; retry (after its restart, or on another replica "
      "with a session store)");
}

// How long a call without a deadline of its own (GetSession, JoinSession, StateForce, WatchSession) may wait for an
// evicted session's restore.
constexpr std::chrono::seconds kLookupDeadline{30};

SessionInfo info_of(ManagedSession& s) {
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

}  // namespace

SessionManager::SessionManager(Engine& engine, ManagerOptions options, Metrics& metrics)
    : engine_(engine),
      options_(std::move(options)),
      metrics_(metrics),
      clock_(options_.clock ? *options_.clock : real_clock()),
      watch_hub_(options_.max_watchers),
      compute_(std::max(1, options_.compute_threads), engine_thread_init),
      registry_(engine_, options_, metrics_, clock_,
                [this](TimePoint deadline, const std::function<absl::Status()>& fn) { return compute(deadline, fn); }) {
  if (options_.reaper_thread) registry_.start_reaper();
}

SessionManager::~SessionManager() = default;

absl::StatusOr<TickView> SessionManager::create(const std::string& tenant, const SessionSource& source,
                                                const SessionOptions& options, int tick_deadline_ms,
                                                const std::string& proposed_id, TimePoint deadline,
                                                std::string* id_out, std::vector<MapFeature>* map) {
  if (draining()) return absl::UnavailableError("the server is draining (shutting down): no new sessions");
  if (tick_deadline_ms < 0) return absl::InvalidArgumentError("tick_deadline_ms must not be negative");
  auto id = registry_.reserve_id(tenant, proposed_id, 0);
  if (!id.ok()) return id.status();
  auto s = std::make_shared<ManagedSession>(clock_);
  s->id = *id;
  s->tenant = tenant;
  s->source = source;
  s->tick_deadline_ms = tick_deadline_ms ? tick_deadline_ms : options_.default_tick_deadline_ms;
  s->saved_at = clock_.now();  // first saved an interval from now
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
  if (auto st2 = registry_.insert(s, /*refuse_when_draining=*/true); !st2.ok()) return st2;
  spdlog::info("session {}: created on {} ({} mode, seed {}, {} Hz, {} agents, {} bytes)", *id,
               source.scenario_name.empty() ? std::string("client-sent scenario") : source.scenario_name,
               session_mode_name(options.mode), options.seed, options.tick_hz, out.view.agents.size(), s->bytes.load());
  *id_out = *id;
  return out;
}

absl::Status SessionManager::run_ticks(ManagedSession& s, const std::vector<ControlInput>& controls, int n,
                                       TimePoint deadline, const std::function<bool()>& cancelled,
                                       std::vector<TickView>* out) {
  int64_t tick;
  {
    std::lock_guard<std::mutex> l(s.mu);
    tick = s.tick;
  }
  auto after = [&](int i, const absl::Status& st) {
    return absl::Status(st.code(), absl::StrCat(st.message(), " (after ", std::to_string(i), " of ", std::to_string(n),
                                                " ticks; the session is at tick ", std::to_string(tick), ")"));
  };
  const std::vector<ControlInput> none;
  for (int i = 0; i < n; ++i) {
    // The poses are for the first tick; later ticks of the call keep the controlled agents' last control.
    const std::vector<ControlInput>& controls_now = i == 0 ? controls : none;
    // Between the ticks of a long call: a client that is gone or out of time gets no more (a slot free at once
    // would otherwise keep computing ticks no one reads). The first tick always runs: in a multi-client session it
    // is every controller's tick, not only this caller's.
    if (i > 0) {
      std::lock_guard<std::mutex> l(s.mu);
      if (s.closed)
        return absl::AbortedError(absl::StrCat("session ", echo_id(s.id), " was closed (CloseSession) after ",
                                               std::to_string(i), " of ", std::to_string(n), " ticks"));
    }
    if (i > 0 && (clock_.now() >= deadline || (cancelled && cancelled()))) {
      const bool late = clock_.now() >= deadline;
      return absl::Status(late ? absl::StatusCode::kDeadlineExceeded : absl::StatusCode::kCancelled,
                          absl::StrCat(late ? "the call's deadline passed" : "the client cancelled the call",
                                       " after ", std::to_string(i), " of ", std::to_string(n),
                                       " ticks; the session is at tick ", std::to_string(tick)));
    }
    // The cache cap holds as sessions grow: room for the largest growth of one tick seen so far, before the tick.
    if (auto st = registry_.room_to_grow(s); !st.ok()) return i == 0 ? st : after(i, st);
    StepResult view;
    // A compute call per tick, not one for the whole request: a long request queues again between its ticks, so a
    // short request on another session waits for one tick rather than for all of them.
    absl::Status st = compute(deadline, [&]() -> absl::Status {
      const auto t0 = std::chrono::steady_clock::now();  // the step's cost in wall time, whatever the clock
      auto r = session_tick(*s.session, controls_now);
      if (!r.ok()) return r.status();
      view = std::move(*r);
      metrics_.count_step(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      return absl::OkStatus();
    });
    if (!st.ok()) return i == 0 || st.code() != absl::StatusCode::kDeadlineExceeded ? st : after(i, st);
    tick = session_tick_index(*s.session);
    ++s.changes;
    const uint64_t before = s.bytes;
    s.bytes = session_memory_bytes(engine_, *s.session) + s.source.womd_bytes.size();
    if (s.bytes > before) s.max_tick_growth = std::max(s.max_tick_growth, s.bytes - before);
    s.touch();  // a long call keeps its session in use: the idle rule must not close it between two ticks
    {
      std::lock_guard<std::mutex> l(s.mu);
      s.tick = tick;
      s.publish(view);
      out->push_back(s.recent.back());
      s.cv.notify_all();
    }
    // A session stepped back to back is never free when the reaper looks (it takes engine_mu only when no call holds
    // it), so its stepping thread saves it here, at a tick boundary, once its snapshot is an interval old. Measured
    // (docs/deployment.md, Snapshots): 17 ms median for the one call an interval that saves, and kill -9 then lost
    // 0.15-0.71 s of sessions stepped back to back at a 1 s interval, where the reaper alone lost them whole.
    // Saving here rather than handing the bytes to a writer thread keeps one owner of a session's saves.
    registry_.save_if_due(s);
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<TickView>> SessionManager::step(const std::string& id, const std::string& tenant,
                                                           const std::string& credential,
                                                           const std::vector<ControlInput>& controls, int num_ticks,
                                                           TimePoint deadline,
                                                           const std::function<bool()>& cancelled) {
  if (draining()) return draining_error();
  auto found = registry_.find(id, tenant, deadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  InCall in_call(s);
  if (num_ticks == 0) num_ticks = 1;
  if (num_ticks < 0 || num_ticks > 1000)
    return absl::InvalidArgumentError(absl::StrCat("num_ticks ", std::to_string(num_ticks), ": must be in 1..1000"));
  std::unique_lock<std::mutex> l(s.mu);
  if (s.closed) return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(id), " was closed"));
  // The barrier gathers poses by agent (several clients, one tick), so what it would merge is refused here: an agent
  // that is not a controller's, or one given twice in this call. The engine checks the poses themselves.
  std::set<int64_t> seen;
  for (size_t i = 0; i < controls.size(); ++i) {
    const std::string where = absl::StrCat("poses[", std::to_string(i), "].agent_id ", std::to_string(controls[i].agent_id));
    if (!s.controllers.count(controls[i].agent_id))
      return absl::InvalidArgumentError(absl::StrCat(where, " is not a controlled agent of session '", id, "'"));
    if (!seen.insert(controls[i].agent_id).second)
      return absl::InvalidArgumentError(absl::StrCat(where, ": the agent is given twice in one request"));
  }
  if (auto st = check_controller_locked(s, credential, controls, "poses", "send its poses"); !st.ok()) return st;
  if (num_ticks > 1 && s.controllers.size() > 1)
    return absl::InvalidArgumentError("num_ticks > 1 is only for sessions with at most one controlled agent");
  auto out = barrier_step(s, l, controls, deadline, [&](const std::vector<ControlInput>& taken, std::vector<TickView>* o) {
    std::unique_lock<std::timed_mutex> e(s.engine_mu, std::defer_lock);
    if (!e.try_lock_until(deadline))
      return absl::DeadlineExceededError("the call's deadline passed while the session was busy");
    if (auto st = s.check_not_moved(); !st.ok()) return st;  // [session store]
    return run_ticks(s, taken, num_ticks, deadline, cancelled, o);
  });
  if (out.ok()) s.touch();
  return out;
}

absl::StatusOr<std::vector<int64_t>> SessionManager::inject(const std::string& id, const std::string& tenant,
                                                            const InjectRequest& r, TimePoint deadline) {
  if (draining()) return draining_error();
  auto found = registry_.find(id, tenant, deadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  InCall in_call(s);
  std::unique_lock<std::timed_mutex> e(s.engine_mu, std::try_to_lock);
  if (!e.owns_lock())
    return absl::AbortedError(absl::StrCat("session '", id, "' is busy with another call; calls are serialised"));
  if (auto st = s.check_not_moved(); !st.ok()) return st;  // [session store]
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
  if (draining()) return draining_error();
  auto found = registry_.find(id, tenant, clock_.now() + kLookupDeadline);
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
  if (auto st = s.check_not_moved(); !st.ok()) return st;  // [session store]
  absl::Status st = session_force(*s.session, r);
  if (st.ok()) ++s.changes;
  return st;
}

absl::StatusOr<std::pair<SessionInfo, TickView>> SessionManager::get(const std::string& id,
                                                                     const std::string& tenant) {
  auto found = registry_.find(id, tenant, clock_.now() + kLookupDeadline);
  if (!found.ok()) return found.status();
  SessionInfo info = info_of(**found);
  std::lock_guard<std::mutex> l((*found)->mu);
  return std::make_pair(info, TickView{(*found)->tick, (*found)->view});
}

std::vector<SessionInfo> SessionManager::list(const std::string& tenant) {
  std::vector<SessionInfo> out;
  for (const auto& s : registry_.of_tenant(tenant)) out.push_back(info_of(*s));
  return out;
}

absl::StatusOr<std::string> SessionManager::fork(const std::string& id, const std::string& tenant,
                                                 const std::string& proposed_id, TimePoint deadline) {
  if (draining()) return absl::UnavailableError("the server is draining (shutting down): no new sessions");
  auto found = registry_.find(id, tenant, deadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  auto nid = registry_.reserve_id(tenant, proposed_id, s.bytes);
  if (!nid.ok()) return nid.status();
  auto f = std::make_shared<ManagedSession>(clock_);
  f->id = *nid;
  f->tenant = tenant;
  f->source = s.source;
  f->tick_deadline_ms = s.tick_deadline_ms;
  f->saved_at = clock_.now();
  {
    std::unique_lock<std::timed_mutex> e(s.engine_mu, std::defer_lock);
    if (!e.try_lock_until(deadline)) return absl::DeadlineExceededError("the session stayed busy past the deadline");
    if (auto st = s.check_not_moved(); !st.ok()) return st;  // [session store]
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
  // Room again at insert: other forks may have filled it while this one waited for its busy source.
  if (auto st = registry_.insert(f, /*refuse_when_draining=*/false); !st.ok()) return st;
  spdlog::info("session {}: forked from {} at tick {}", *nid, id, f->tick);
  return *nid;
}

absl::Status SessionManager::check_controller_locked(const ManagedSession& s, const std::string& credential,
                                                    const std::vector<ControlInput>& agents, const char* field,
                                                    const char* action) {
  // The session keeps each credential's digest only (it is saved in snapshot files).
  const std::string digest = credential.empty() ? std::string() : secret_digest(credential);
  if (!credential.empty()) {
    bool issued = false;
    for (const auto& [agent, c] : s.controller_of) issued = issued || c == digest;
    if (!issued)
      return absl::PermissionDeniedError(absl::StrCat("controller_credential is not one that session '", s.id,
                                                      "' issued (JoinSession gives one)"));
  }
  for (size_t i = 0; i < agents.size(); ++i) {
    auto it = s.controller_of.find(agents[i].agent_id);
    if (it != s.controller_of.end() && it->second != digest)
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
  if (draining()) return draining_error();
  auto found = registry_.find(id, tenant, clock_.now() + kLookupDeadline);
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
    if (it != s.controller_of.end() && (credential.empty() || it->second != secret_digest(credential)))
      return absl::AlreadyExistsError(
          absl::StrCat(where, " of session '", id, "' already has a controller (another client joined for it)"));
  }
  JoinResult out;
  out.credential = credential.empty() ? random_session_id() : credential;
  const std::string digest = secret_digest(out.credential);
  for (int64_t a : agent_ids) s.controller_of[a] = digest;
  for (const auto& [agent, c] : s.controller_of)
    if (c == digest) out.agents.push_back(agent);
  ++s.changes;  // the claims are saved with the session
  spdlog::info("session {}: a client joined as the controller of {} agents", id, agent_ids.size());
  return out;
}

absl::Status SessionManager::watch_add(const std::string& id, const std::string& tenant,
                                       std::shared_ptr<TickWatcher> w) {
  if (draining()) return absl::UnavailableError("the server is draining (shutting down): no new watch streams");
  auto found = registry_.find(id, tenant, clock_.now() + kLookupDeadline);
  if (!found.ok()) return found.status();
  ManagedSession& s = **found;
  if (auto st = watch_hub_.reserve(); !st.ok()) return st;
  std::lock_guard<std::mutex> l(s.mu);
  if (s.closed) {
    watch_hub_.release();
    return absl::FailedPreconditionError(absl::StrCat("session ", echo_id(id), " was closed"));
  }
  s.watchers.add(std::move(w), {s.tick, s.view});
  return absl::OkStatus();
}

}  // namespace ss::server
