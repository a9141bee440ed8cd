// The server's sessions by id: ids, the caps (session count, total cache bytes), LRU eviction with a snapshot first,
// restoring evicted sessions on their next call, snapshots (background, on drain, on restart), and the reaper that
// closes idle sessions, writes the background snapshots and purges the allocator after closes. Tenants see only
// their own sessions: another tenant's id is answered as an unknown one.
#pragma once

#include <atomic>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"
#include "server/managed_session.h"
#include "server/metrics.h"
#include "server/session_leases.h"
#include "server/snapshot.h"

namespace ss::server {

// Runs an engine call on a compute thread, or DEADLINE_EXCEEDED when none takes it by the deadline.
using ComputeFn = std::function<absl::Status(TimePoint deadline, const std::function<absl::Status()>& fn)>;

// The one answer for an id the caller cannot see: unknown, closed, or another tenant's.
absl::Status not_found(const std::string& id);

class SessionRegistry {
 public:
  SessionRegistry(Engine& engine, const ManagerOptions& options, Metrics& metrics, const Clock& clock,
                  ComputeFn compute);
  // Stops the reaper.
  ~SessionRegistry();

  // A free id (`proposed`, or a random one for ""), with room under the caps and `tenant`'s share for one more
  // session of `bytes` (evicting idle sessions if needed). INVALID_ARGUMENT for an id that breaks the rule,
  // ALREADY_EXISTS for one in use, RESOURCE_EXHAUSTED when nothing can be evicted.
  absl::StatusOr<std::string> reserve_id(const std::string& tenant, const std::string& proposed, uint64_t bytes);
  // Lists `s` under its id, again with room under the caps (others may have filled it meanwhile). With
  // `refuse_when_draining`, UNAVAILABLE once the server drains.
  absl::Status insert(const std::shared_ptr<ManagedSession>& s, bool refuse_when_draining);
  // The session `id` of `tenant` (restored if it was evicted); NOT_FOUND alike for unknown ids and other tenants'.
  absl::StatusOr<std::shared_ptr<ManagedSession>> find(const std::string& id, const std::string& tenant,
                                                       TimePoint deadline);
  // Closes `id` if `tenant` is null or its tenant (the reaper closes any tenant's idle sessions).
  absl::Status close(const std::string& id, const std::string* tenant);
  // Every open session of `tenant`.
  std::vector<std::shared_ptr<ManagedSession>> of_tenant(const std::string& tenant);
  // Room under --max_cache_mb for one more tick of `s` (its largest growth so far), evicting idle sessions if needed.
  absl::Status room_to_grow(ManagedSession& s);
  int count();
  uint64_t total_bytes();

  // Refuses what would restore or add sessions, and ends every watch stream.
  void start_draining();
  bool draining() const { return draining_; }
  // Saves every session to the snapshot directory (after the gRPC server stopped).
  int save_all();
  // Restores every snapshot of the snapshot directory; returns how many.
  int restore_all();

  // Saves `s` when it changed and its snapshot is --snapshot_interval_s old: called by the thread stepping it, holding
  // its engine_mu, at a tick boundary (the reaper cannot take a session stepped back to back).
  void save_if_due(ManagedSession& s);

  // One pass of the reaper: the allocator purge, the background snapshots, closing idle sessions, each when due.
  void reap();
  void start_reaper();

 private:
  // Evicts idle sessions other than `keep` (LRU) until `extra_sessions` more sessions and `extra_bytes` more bytes
  // of `tenant` fit under the caps and its share (over its share, only its own sessions go); RESOURCE_EXHAUSTED,
  // naming only the caller's figures, when they cannot. Without a snapshot directory nothing is evicted: an evicted
  // session would be lost. Holds mu_.
  absl::Status make_room_locked(const std::string& tenant, uint64_t extra_bytes, int extra_sessions = 1,
                                const ManagedSession* keep = nullptr);
  absl::Status evict_locked(const std::shared_ptr<ManagedSession>& s);
  // Saves `s` to the snapshot directory or the session store (with `release`, giving up its lease there).
  absl::Status save(ManagedSession& s, bool release = false);
  Snapshot snapshot_of(ManagedSession& s);
  // save(), logging a failure as `what`, then removing the file again if the session was closed meanwhile. Holds
  // s.engine_mu.
  bool save_kept(ManagedSession& s, const char* what);
  absl::StatusOr<std::shared_ptr<ManagedSession>> restore_from(Snapshot snap, TimePoint deadline);
  // Saves every session that changed since its last snapshot (the background snapshots).
  void save_changed();
  bool evicted_contains(const std::string& id);
  // Moves the snapshot of `id` to the quarantine when `read` (read_snapshot's answer) says it is corrupt.
  void quarantine_if_corrupt(const std::string& id, const absl::Status& read);
  struct Held {
    int sessions = 0;
    uint64_t bytes = 0;
  };
  // What the sessions of `tenant` (null: of every tenant) hold. Holds mu_.
  Held held_locked(const std::string* tenant) const;

  // --- The shared session store (server/session_registry_store.cc; only with ManagerOptions::session_store) ---
  // find() and close() for sessions that may be held by another replica, or by none since one died.
  absl::StatusOr<std::shared_ptr<ManagedSession>> find_in_store(const std::string& id, const std::string& tenant,
                                                                TimePoint deadline);
  absl::Status close_in_store(const std::string& id, const std::string* tenant);
  // A new session's lease and first snapshot (ALREADY_EXISTS when another replica has the id).
  absl::Status claim_in_store(ManagedSession& s);
  // The lease keeper's hooks: another replica asked for `id` / took it.
  bool hand_over(const std::string& id);
  void lease_lost(const std::string& id, const std::string& owner);
  // Takes `s` out of this replica's memory (moved or stale), leaving the store's copy alone.
  void drop_local(const std::shared_ptr<ManagedSession>& s, const char* why);

  Engine& engine_;
  const ManagerOptions& options_;
  Metrics& metrics_;
  const Clock& clock_;
  ComputeFn compute_;
  std::mutex mu_;
  std::map<std::string, std::shared_ptr<ManagedSession>> sessions_;
  std::map<std::string, std::string> evicted_;  // id -> tenant: saved to the snapshot directory, restored on next call
  std::atomic<bool> draining_{false};
  std::atomic<int> closed_since_trim_{0};  // sessions closed or evicted since the reaper's last allocator purge
  TimePoint last_save_, last_trim_;        // the reaper's (its thread's, or reap()'s caller's)
  std::mutex reaper_mu_;
  std::condition_variable reaper_cv_;
  bool stop_ = false;  // under reaper_mu_
  std::atomic<bool> stopping_{false};
  std::thread reaper_;
  // The store's side (server/session_registry_store.cc). Last, so its thread stops before the members it uses.
  std::map<std::string, std::string> lost_;  // id -> the replica that took its lease; under mu_
  std::unique_ptr<LeaseKeeper> leases_;
};

}  // namespace ss::server
