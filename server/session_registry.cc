#include "server/session_registry.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "server/allocator.h"
#include "server/session_id.h"
#include "spdlog/spdlog.h"

namespace ss::server {

absl::Status not_found(const std::string& id) {
  return absl::NotFoundError(absl::StrCat("session_id ", echo_id(id), " is not an open session"));
}

SessionRegistry::SessionRegistry(Engine& engine, const ManagerOptions& options, Metrics& metrics, const Clock& clock,
                                 ComputeFn compute)
    : engine_(engine),
      options_(options),
      metrics_(metrics),
      clock_(clock),
      compute_(std::move(compute)),
      last_save_(clock.now()),
      last_trim_(clock.now()) {
  // [session store] the lease keeper, with its hooks into this registry (server/session_registry_store.cc).
  if (options_.session_store)
    leases_ = std::make_unique<LeaseKeeper>(
        *options_.session_store,
        LeaseKeeper::Hooks{[this](const std::string& id) { return hand_over(id); },
                           [this](const std::string& id, const std::string& owner) { lease_lost(id, owner); }});
}

SessionRegistry::~SessionRegistry() {
  {
    std::lock_guard<std::mutex> l(reaper_mu_);
    stop_ = true;
  }
  stopping_ = true;
  reaper_cv_.notify_all();
  if (reaper_.joinable()) reaper_.join();
  leases_.reset();  // [session store] its thread calls into the registry
}

void SessionRegistry::start_reaper() {
  reaper_ = std::thread([this] {
    std::unique_lock<std::mutex> l(reaper_mu_);
    while (!stop_) {
      // Checks ten times a second; a pass does each job only when it is due.
      const TimePoint next = clock_.now() + std::chrono::milliseconds(100);
      while (!stop_ && clock_.now() < next) clock_.wait_until(l, reaper_cv_, next);
      if (stop_) return;
      l.unlock();
      reap();
      l.lock();
    }
  });
}

int SessionRegistry::count() {
  std::lock_guard<std::mutex> l(mu_);
  return static_cast<int>(sessions_.size());
}

uint64_t SessionRegistry::total_bytes() {
  std::lock_guard<std::mutex> l(mu_);
  return held_locked(nullptr).bytes;
}

absl::StatusOr<std::string> SessionRegistry::reserve_id(const std::string& tenant, const std::string& proposed,
                                                        uint64_t bytes) {
  std::lock_guard<std::mutex> l(mu_);
  std::string id;
  if (proposed.empty()) {
    id = random_session_id();
  } else {
    if (auto st = check_session_id(proposed); !st.ok()) return st;
    if (sessions_.count(proposed) || evicted_.count(proposed))
      return absl::AlreadyExistsError(absl::StrCat("session_id ", echo_id(proposed), " is already in use"));
    id = proposed;
  }
  if (auto st = make_room_locked(tenant, bytes); !st.ok()) return st;
  return id;
}

absl::Status SessionRegistry::insert(const std::shared_ptr<ManagedSession>& s, bool refuse_when_draining) {
  if (leases_ && !(refuse_when_draining && draining_))  // [session store] the id cluster-wide, first snapshot
    if (auto st = claim_in_store(*s); !st.ok()) return st;
  std::lock_guard<std::mutex> l(mu_);
  absl::Status st;
  if (refuse_when_draining && draining_)
    st = absl::UnavailableError("the server is draining (shutting down): no new sessions");
  else if (sessions_.count(s->id))
    st = absl::AlreadyExistsError(absl::StrCat("session_id ", echo_id(s->id), " is already in use"));
  else
    st = make_room_locked(s->tenant, s->bytes);
  if (!st.ok()) {
    if (leases_) (void)leases_->remove(s->id);  // [session store] not listed after all
    return st;
  }
  sessions_[s->id] = s;
  return absl::OkStatus();
}

Snapshot SessionRegistry::snapshot_of(ManagedSession& s) {
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
  return snap;
}

absl::Status SessionRegistry::save(ManagedSession& s, bool release) {
  const uint64_t changes = s.changes;
  const Snapshot snap = snapshot_of(s);
  absl::Status st = leases_ ? leases_->put(s.id, encode_snapshot(snap), release)  // [session store]
                            : write_snapshot(options_.snapshot_dir, snap);
  if (st.ok()) {
    s.saved_changes = changes;
    s.saved_at = clock_.now();
  }
  return st;
}

bool SessionRegistry::save_kept(ManagedSession& s, const char* what) {
  if (auto st = save(s); !st.ok()) {
    spdlog::warn("session {}: {} failed: {}", s.id, what, std::string(st.message()));
    return false;
  }
  bool closed;
  {
    std::lock_guard<std::mutex> l(s.mu);
    closed = s.closed;
  }
  // A CloseSession that ran while the file was written removed it before the write renamed it into place. (The
  // session store refuses a put after a close: the close removed the lease's epoch.)
  if (closed && !leases_ && !evicted_contains(s.id)) remove_snapshot(options_.snapshot_dir, s.id);
  return true;
}

void SessionRegistry::save_if_due(ManagedSession& s) {
  if ((options_.snapshot_dir.empty() && !leases_) || options_.snapshot_interval_s <= 0 || draining_) return;
  if (s.changes == s.saved_changes ||
      clock_.now() - s.saved_at < std::chrono::duration<double>(options_.snapshot_interval_s))
    return;
  const auto t0 = std::chrono::steady_clock::now();  // the save's cost to this call, in wall time whatever the clock
  if (save_kept(s, "snapshot at a tick boundary"))
    spdlog::debug("session {}: saved at tick boundary in {:.2f} ms", s.id,
                  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

absl::Status SessionRegistry::evict_locked(const std::shared_ptr<ManagedSession>& s) {
  std::unique_lock<std::timed_mutex> e(s->engine_mu, std::try_to_lock);
  if (!e.owns_lock()) return absl::AbortedError("busy");
  if (leases_) {  // [session store] saved there with its lease given up: restored by the next call, here or elsewhere
    if (auto st = save(*s, /*release=*/true); !st.ok()) return st;
    s->moved = true;
  } else if (!options_.snapshot_dir.empty()) {
    if (auto st = save(*s); !st.ok()) return st;
    evicted_[s->id] = s->tenant;
  }
  {
    std::lock_guard<std::mutex> l(s->mu);
    s->close_locked();
  }
  sessions_.erase(s->id);
  ++closed_since_trim_;
  metrics_.count_eviction();
  spdlog::info("session {}: evicted after {:.1f} s idle, snapshot saved", s->id, s->idle_seconds());
  return absl::OkStatus();
}

SessionRegistry::Held SessionRegistry::held_locked(const std::string* tenant) const {
  Held h;
  for (const auto& [id, s] : sessions_)
    if (tenant == nullptr || s->tenant == *tenant) {
      ++h.sessions;
      h.bytes += s->bytes;
    }
  return h;
}

absl::Status SessionRegistry::make_room_locked(const std::string& tenant, uint64_t extra_bytes, int extra_sessions,
                                               const ManagedSession* keep) {
  const int share_sessions = options_.tenant_max_sessions > 0 ? options_.tenant_max_sessions : options_.max_sessions;
  const uint64_t share_bytes =
      options_.tenant_max_cache_bytes > 0 ? options_.tenant_max_cache_bytes : options_.max_cache_bytes;
  while (true) {
    const Held mine = held_locked(&tenant), all = held_locked(nullptr);
    // Over the caller's own share (where it is smaller than the cap), only its own idle sessions may make room.
    const bool own_only =
        (share_sessions < options_.max_sessions && mine.sessions + extra_sessions > share_sessions) ||
        (share_bytes < options_.max_cache_bytes && mine.bytes + extra_bytes > share_bytes);
    if (!own_only && all.sessions + extra_sessions <= options_.max_sessions &&
        all.bytes + extra_bytes <= options_.max_cache_bytes)
      return absl::OkStatus();
    // Without a snapshot directory (or the session store) an evicted session would be lost: nothing is evicted.
    std::vector<std::shared_ptr<ManagedSession>> idle;
    if (!options_.snapshot_dir.empty() || leases_)
      for (const auto& [id, s] : sessions_)
        if (s.get() != keep && (!own_only || s->tenant == tenant) && s->calls == 0 &&
            s->idle_seconds() >= options_.evict_idle_s)
          idle.push_back(s);
    std::sort(idle.begin(), idle.end(), [](const auto& a, const auto& b) { return a->last_used < b->last_used; });
    bool evicted = false;
    for (const auto& s : idle)
      if (evict_locked(s).ok()) {
        evicted = true;
        break;
      }
    if (evicted) continue;
    // The message gives the caller's own figures and the flags' values: nothing of other tenants' sessions.
    return absl::ResourceExhaustedError(absl::StrCat(
        own_only ? absl::StrCat("your share of the server is full (--tenant_max_sessions=",
                                std::to_string(share_sessions), ", --tenant_max_cache_mb=",
                                std::to_string(share_bytes >> 20), ")")
                 : absl::StrCat("the server is full (--max_sessions=", std::to_string(options_.max_sessions),
                                ", --max_cache_mb=", std::to_string(options_.max_cache_bytes >> 20), ")"),
        options_.snapshot_dir.empty() && !leases_
            ? std::string(" and, without --snapshot_dir, evicts no session to make room")
            : absl::StrCat(" and no session has been idle for --evict_idle_s=", std::to_string(options_.evict_idle_s),
                           " s to be evicted"),
        "; your sessions here: ", std::to_string(mine.sessions), " holding ", std::to_string(mine.bytes >> 20),
        " MiB, ", std::to_string(extra_bytes >> 20), " MiB more needed. Close one of yours or retry later"));
  }
}

absl::Status SessionRegistry::room_to_grow(ManagedSession& s) {
  std::lock_guard<std::mutex> l(mu_);
  absl::Status st = make_room_locked(s.tenant, s.max_tick_growth, 0, &s);
  if (st.ok()) return st;
  return absl::ResourceExhaustedError(absl::StrCat(
      "session '", s.id, "' (", std::to_string(s.bytes.load()), " bytes, up to ", std::to_string(s.max_tick_growth),
      " more a tick) has no room to grow: ", st.message()));
}

absl::StatusOr<std::shared_ptr<ManagedSession>> SessionRegistry::find(const std::string& id,
                                                                      const std::string& tenant, TimePoint deadline) {
  if (leases_) return find_in_store(id, tenant, deadline);  // [session store]
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
  auto snap = read_snapshot(options_.snapshot_dir, id);
  if (!snap.ok()) {
    if (snap.status().code() == absl::StatusCode::kDataLoss) {
      std::lock_guard<std::mutex> l(mu_);
      evicted_.erase(id);
    }
    quarantine_if_corrupt(id, snap.status());
    return snap.status();
  }
  auto s = restore_from(std::move(*snap), deadline);
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
  if (auto st = make_room_locked(tenant, (*s)->bytes); !st.ok()) return st;
  evicted_.erase(id);
  sessions_[id] = *s;
  // The snapshot stays until the session closes: a crash before the next save still finds it.
  spdlog::info("session {}: restored from its eviction snapshot at tick {}", id, (*s)->tick);
  return *s;
}

absl::StatusOr<std::shared_ptr<ManagedSession>> SessionRegistry::restore_from(Snapshot snap, TimePoint deadline) {
  const std::string path = *snapshot_path(options_.snapshot_dir, snap.session_id);
  auto s = std::make_shared<ManagedSession>(clock_);
  s->id = snap.session_id;
  s->tenant = snap.tenant;
  s->source = snap.source;
  s->tick_deadline_ms = snap.tick_deadline_ms;
  absl::Status st = compute_(deadline, [&] {
    auto session = session_restore(engine_, snap.source, snap.session_bytes);
    if (!session.ok()) return session.status();
    s->session = std::move(*session);
    s->bytes = session_memory_bytes(engine_, *s->session) + s->source.womd_bytes.size();
    return absl::OkStatus();
  });
  if (!st.ok()) return absl::Status(st.code(), absl::StrCat("snapshot ", path, ": ", std::string(st.message())));
  s->touch();
  s->saved_changes = s->changes;  // its snapshot is on disk already
  s->saved_at = clock_.now();
  std::lock_guard<std::mutex> l(s->mu);
  s->tick = session_tick_index(*s->session);
  s->controller_of.insert(snap.controllers.begin(), snap.controllers.end());
  s->publish(session_view(*s->session));
  return s;
}

absl::Status SessionRegistry::close(const std::string& id, const std::string* tenant) {
  if (leases_) return close_in_store(id, tenant);  // [session store]
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
    s->close_locked();
    spdlog::info("session {}: closed at tick {}", id, s->tick);
  }
  // A background save running now checks `closed` after writing and removes its file too.
  if (!options_.snapshot_dir.empty()) remove_snapshot(options_.snapshot_dir, id);
  s.reset();  // freed now unless a call still holds it: then the reaper's purge after a later close takes it
  ++closed_since_trim_;
  return absl::OkStatus();
}

std::vector<std::shared_ptr<ManagedSession>> SessionRegistry::of_tenant(const std::string& tenant) {
  std::vector<std::shared_ptr<ManagedSession>> all;
  std::lock_guard<std::mutex> l(mu_);
  for (const auto& [id, s] : sessions_)
    if (s->tenant == tenant) all.push_back(s);
  return all;
}

void SessionRegistry::start_draining() {
  draining_ = true;
  std::lock_guard<std::mutex> l(mu_);
  for (const auto& [id, s] : sessions_) {
    std::lock_guard<std::mutex> sl(s->mu);
    s->watchers.end();
  }
}

int SessionRegistry::save_all() {
  if (options_.snapshot_dir.empty() && !leases_) return 0;
  std::vector<std::shared_ptr<ManagedSession>> all;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, s] : sessions_) all.push_back(s);
  }
  int saved = 0;
  for (const auto& s : all) {
    std::lock_guard<std::timed_mutex> e(s->engine_mu);
    // [session store] with its lease given up, so another replica takes it at once
    if (auto st = save(*s, /*release=*/leases_ != nullptr); !st.ok()) {
      spdlog::error("session {}: snapshot failed: {}", s->id, std::string(st.message()));
      continue;
    }
    ++saved;
  }
  return saved;
}

int SessionRegistry::restore_all() {
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
      quarantine_if_corrupt(id, snap.status());
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
    auto s = restore_from(std::move(*snap), clock_.now() + std::chrono::minutes(10));
    if (!s.ok()) {
      spdlog::error("session {}: not restored: {}", id, std::string(s.status().message()));
      continue;
    }
    {
      std::lock_guard<std::mutex> l(mu_);
      if (held_locked(nullptr).bytes + (*s)->bytes > options_.max_cache_bytes) {
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

void SessionRegistry::save_changed() {
  std::vector<std::shared_ptr<ManagedSession>> all;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, s] : sessions_) all.push_back(s);
  }
  int saved = 0;
  for (const auto& s : all) {
    if (stopping_ || draining_) return;
    // A session busy in an engine call is saved by that call at its next tick boundary (save_if_due).
    std::unique_lock<std::timed_mutex> e(s->engine_mu, std::try_to_lock);
    if (!e.owns_lock() || s->changes == s->saved_changes) continue;
    bool ok = false;
    absl::Status st = compute_(clock_.now() + std::chrono::seconds(10), [&] {
      ok = save_kept(*s, "background snapshot");
      return absl::OkStatus();
    });
    if (!st.ok()) spdlog::warn("session {}: background snapshot not run: {}", s->id, std::string(st.message()));
    saved += ok;
  }
  if (saved) spdlog::debug("background snapshots: {} sessions saved", saved);
}

void SessionRegistry::quarantine_if_corrupt(const std::string& id, const absl::Status& read) {
  // A cut or corrupt file is never read again; one of another format version stays for the server that reads it.
  if (read.code() != absl::StatusCode::kDataLoss) return;
  auto to = quarantine_snapshot(options_.snapshot_dir, id);
  if (to.ok())
    spdlog::warn("session {}: its corrupt snapshot moved to quarantine: {}", id, *to);
  else
    spdlog::error("session {}: its corrupt snapshot could not be moved to quarantine: {}", id,
                  std::string(to.status().message()));
}

bool SessionRegistry::evicted_contains(const std::string& id) {
  std::lock_guard<std::mutex> l(mu_);
  return evicted_.count(id) > 0;
}

void SessionRegistry::reap() {
  // Give what closed sessions freed back to the kernel now (docs/performance.md; server/allocator.h), rather than when
  // jemalloc's decay gets to it: an idle arena's dirty pages decay only when it allocates again.
  if (options_.malloc_trim_interval_s > 0 && closed_since_trim_ > 0 &&
      clock_.now() - last_trim_ >= std::chrono::duration<double>(options_.malloc_trim_interval_s)) {
    const int closed = closed_since_trim_.exchange(0);
    const auto t0 = std::chrono::steady_clock::now();  // the purge's own cost, in wall time whatever the clock
    const int64_t released = allocator_trim();
    last_trim_ = clock_.now();
    metrics_.count_malloc_trim();
    spdlog::debug("allocator purge after {} sessions closed: RSS {:+.1f} MB in {:.1f} ms", closed,
                  -static_cast<double>(released) / (1 << 20),
                  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  if ((!options_.snapshot_dir.empty() || leases_) && options_.snapshot_interval_s > 0 &&
      clock_.now() - last_save_ >= std::chrono::duration<double>(options_.snapshot_interval_s)) {
    save_changed();
    last_save_ = clock_.now();
  }
  std::vector<std::string> expired;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& [id, s] : sessions_)
      if (s->idle_seconds() > options_.idle_timeout_s) expired.push_back(id);
  }
  for (const std::string& id : expired) {
    spdlog::info("session {}: idle for more than --idle_timeout_s={}, closing", id, options_.idle_timeout_s);
    (void)close(id, nullptr);
  }
}

}  // namespace ss::server
