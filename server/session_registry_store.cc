// The registry with a shared session store (ManagerOptions::session_store, server/session_store.h): a session lives
// in the store, and in the memory of the one replica whose lease names it. A call that reaches a replica without it
// takes the lease (the holder hands the session over within a quarter of --lease_ms, or its lease runs out if it
// died) and restores the session from the store's snapshot; a replica that finds its lease taken drops its stale copy
// and refuses the call, so a session's history never forks.
#include "absl/strings/str_cat.h"
#include "server/session_id.h"
#include "server/session_registry.h"
#include "spdlog/spdlog.h"

namespace ss::server {

absl::StatusOr<std::shared_ptr<ManagedSession>> SessionRegistry::find_in_store(const std::string& id,
                                                                              const std::string& tenant,
                                                                              TimePoint deadline) {
  if (!check_session_id(id).ok()) return not_found(id);
  std::shared_ptr<ManagedSession> s;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) {
      if (it->second->tenant != tenant) return not_found(id);
      s = it->second;
    } else if (auto lost = lost_.find(id); lost != lost_.end()) {
      // Told once: the client learns that the ticks this replica made since its last snapshot are not the session's.
      const std::string owner = lost->second;
      lost_.erase(lost);
      return absl::FailedPreconditionError(absl::StrCat(
          "session ", echo_id(id), ": lease lost", owner.empty() ? "" : absl::StrCat(" to replica '", owner, "'"),
          " (this replica could not renew it in time); its copy here was stale and is dropped: the session continues "
          "from the store's snapshot"));
    }
  }
  if (s) {
    absl::Status st = leases_->hold(id);
    if (st.ok()) {
      s->touch();
      return s;
    }
    if (st.code() == absl::StatusCode::kFailedPrecondition) {
      drop_local(s, "lease lost");
      return st;
    }
    if (st.code() != absl::StatusCode::kNotFound) return st;  // the store cannot be reached to renew it
    // Handed over a moment ago: take it back below, like any session held elsewhere.
  }
  if (draining_) return absl::UnavailableError("the server is draining: sessions are not taken over now; retry");
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - clock_.now());
  if (left.count() <= 0) return absl::DeadlineExceededError("the call's deadline passed before its session was found");
  // A live holder hands the session over within a quarter of its lease; a dead one's lease runs out within one.
  const auto wait = std::min(left, std::chrono::milliseconds(3 * leases_->store().options().lease_ms));
  auto bytes = leases_->acquire(id, tenant, wait);
  if (!bytes.ok()) return bytes.status().code() == absl::StatusCode::kNotFound ? not_found(id) : bytes.status();
  auto snap = decode_snapshot(*bytes, id, absl::StrCat("session store ", leases_->store().where(), " snapshot of ",
                                                        echo_id(id)));
  if (!snap.ok() || snap->tenant != tenant) {
    leases_->release(id);
    if (!snap.ok()) return snap.status();
    return not_found(id);
  }
  auto r = restore_from(std::move(*snap), deadline);
  if (!r.ok()) {
    leases_->release(id);
    return r.status();
  }
  std::lock_guard<std::mutex> l(mu_);
  auto it = sessions_.find(id);
  if (it != sessions_.end()) return it->second;  // another call restored it first (the same snapshot)
  if (auto st = make_room_locked((*r)->tenant, (*r)->bytes); !st.ok()) {
    leases_->release(id);
    return st;
  }
  sessions_[id] = *r;
  spdlog::info("session {}: taken over from the session store at tick {}", id, (*r)->tick);
  return *r;
}

absl::Status SessionRegistry::close_in_store(const std::string& id, const std::string* tenant) {
  std::shared_ptr<ManagedSession> s;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) {
      if (tenant != nullptr && it->second->tenant != *tenant) return not_found(id);
      s = it->second;
      sessions_.erase(it);
    }
  }
  if (s) {
    std::lock_guard<std::mutex> l(s->mu);
    s->close_locked();
    spdlog::info("session {}: closed at tick {}", id, s->tick);
    ++closed_since_trim_;
  } else {
    // Held by another replica or by none: take its lease (the holder hands it over), then delete it.
    if (tenant == nullptr || !check_session_id(id).ok()) return not_found(id);
    const auto wait = std::chrono::milliseconds(3 * leases_->store().options().lease_ms);
    auto bytes = leases_->acquire(id, *tenant, wait);
    if (!bytes.ok()) return bytes.status().code() == absl::StatusCode::kNotFound ? not_found(id) : bytes.status();
    spdlog::info("session {}: closed (it was in the session store)", id);
  }
  absl::Status st = leases_->remove(id);
  if (st.code() == absl::StatusCode::kFailedPrecondition) return st;  // lost: it lives on at the replica named
  if (!st.ok()) spdlog::warn("session {}: closed here, but not removed from the session store: {}", id,
                             std::string(st.message()));
  return absl::OkStatus();
}

absl::Status SessionRegistry::claim_in_store(ManagedSession& s) {
  return leases_->create(s.id, s.tenant, encode_snapshot(snapshot_of(s)));
}

bool SessionRegistry::hand_over(const std::string& id) {
  std::shared_ptr<ManagedSession> s;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) s = it->second;
  }
  // Not listed yet (a call is restoring it here): handed over at the next renewal, once it is.
  if (!s) return false;
  // A call computing on it finishes first; the renewals of the other sessions wait at most this long.
  std::unique_lock<std::timed_mutex> e(s->engine_mu, std::defer_lock);
  if (!e.try_lock_for(std::chrono::milliseconds(leases_->store().options().lease_ms / 8))) return false;
  if (s->moved) return true;
  s->moved = true;  // under engine_mu: no call computes on this copy after the save below
  absl::Status st = save(*s, /*release=*/true);
  if (!st.ok() && st.code() != absl::StatusCode::kFailedPrecondition) {
    s->moved = false;
    spdlog::warn("session {}: not handed over (tried again at the next renewal): {}", id, std::string(st.message()));
    return false;
  }
  e.unlock();
  drop_local(s, st.ok() ? "handed over to the replica that asked for it" : "lease lost");
  return st.ok();
}

void SessionRegistry::lease_lost(const std::string& id, const std::string& owner) {
  std::shared_ptr<ManagedSession> s;
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(id);
    if (it == sessions_.end()) return;
    s = it->second;
    lost_[id] = owner;
  }
  drop_local(s, "lease lost");
}

void SessionRegistry::drop_local(const std::shared_ptr<ManagedSession>& s, const char* why) {
  {
    std::lock_guard<std::mutex> l(mu_);
    auto it = sessions_.find(s->id);
    if (it != sessions_.end() && it->second == s) sessions_.erase(it);
  }
  s->moved = true;
  int64_t tick;
  {
    std::lock_guard<std::mutex> l(s->mu);
    s->close_locked();
    tick = s->tick;
  }
  ++closed_since_trim_;
  spdlog::info("session {}: dropped from this replica at tick {} ({})", s->id, tick, why);
}

}  // namespace ss::server
