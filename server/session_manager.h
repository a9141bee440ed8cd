// The server's sessions: ids, limits (session count, total cache bytes), idle timeout, LRU eviction with a snapshot
// first, the tick barrier of multi-client sessions, watchers, and snapshots on drain. It decides *when* an engine call
// runs and on which session; what a step does is the engine's (engine/scenestreamer.h).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"
#include "server/compute_queue.h"
#include "server/metrics.h"
#include "server/snapshot.h"

namespace ss::server {

using Clock = std::chrono::steady_clock;

struct ManagerOptions {
  std::string snapshot_dir;          // empty: no snapshots (eviction then drops the session)
  double snapshot_interval_s = 30;   // changed sessions are saved this often (0: only on eviction and SIGTERM)
  int max_sessions = 256;
  uint64_t max_cache_bytes = uint64_t{8} << 30;
  double idle_timeout_s = 3600;      // a session unused this long is closed
  double evict_idle_s = 30;          // a session unused this long may be evicted (LRU) to make room
  int compute_threads = 2;           // engine calls running at once
  int default_tick_deadline_ms = 2000;
  int max_watchers = 1024;           // WatchSession streams open at once, over all sessions
  // Once sessions closed (or were evicted), at most this often: an allocator purge from the reaper thread, so what
  // they freed leaves the resident set now rather than at jemalloc's decay (server/allocator.h). 0: never.
  double malloc_trim_interval_s = 0;
};

struct SessionInfo {
  std::string id;
  std::string scenario_name;
  SessionOptions options;
  int tick_hz = 2;
  int64_t tick = 0;
  int step = 0;
  int num_agents = 0;
  uint64_t memory_bytes = 0;
  double idle_seconds = 0;
  std::vector<int64_t> controlled;
};

// JoinSession's answer: the caller's controller credential and every agent it controls.
struct JoinResult {
  std::string credential;
  std::vector<int64_t> agents;
};

struct TickView {
  int64_t tick = 0;
  StepResult view;
};

struct ManagedSession;

// Receives one session's ticks as they are computed (a WatchSession stream), with no thread of its own. The manager
// calls it with its locks held, so it must not block or call the manager back; it may call gRPC (whose reactions
// may run inline, so the watcher's own lock must allow that).
class TickWatcher {
 public:
  virtual ~TickWatcher() = default;
  // A tick, the current one first.
  virtual void on_tick(const TickView& t) = 0;
  // No more ticks: the session closed or was evicted, or the server drains.
  virtual void on_end() = 0;
  // True once the stream is over (the manager then drops it).
  virtual bool done() const = 0;
};

// Every call names the caller's tenant (server/auth.h; "" without --tokens_file). A session belongs to the tenant that
// created it: for any other tenant every call on it answers NOT_FOUND with the message of an unknown id, and list()
// leaves it out. Agents claimed by join() take poses (step) and forces (state_force) only with their credential.
class SessionManager {
 public:
  SessionManager(Engine& engine, ManagerOptions options, Metrics& metrics);
  ~SessionManager();

  // A new session for `tenant`; its id in `id`, and its scenario's map features in `map` when given (CreateSession's
  // include_map).
  absl::StatusOr<TickView> create(const std::string& tenant, const SessionSource& source,
                                  const SessionOptions& options, int tick_deadline_ms, const std::string& proposed_id,
                                  Clock::time_point deadline, std::string* id, std::vector<MapFeature>* map = nullptr);
  // One call's ticks. In a multi-client session the caller waits for the other controllers (or the tick deadline).
  // `credential`: JoinSession's, for agents with a controller (PERMISSION_DENIED for their poses without it).
  absl::StatusOr<std::vector<TickView>> step(const std::string& id, const std::string& tenant,
                                             const std::string& credential, const std::vector<ControlInput>& controls,
                                             int num_ticks, Clock::time_point deadline,
                                             const std::function<bool()>& cancelled = {});
  absl::StatusOr<std::vector<int64_t>> inject(const std::string& id, const std::string& tenant, const InjectRequest& r,
                                              Clock::time_point deadline);
  absl::Status state_force(const std::string& id, const std::string& tenant, const std::string& credential,
                           const StateForceRequest& r);
  absl::Status close(const std::string& id, const std::string& tenant);
  absl::StatusOr<std::pair<SessionInfo, TickView>> get(const std::string& id, const std::string& tenant);
  // The fork belongs to the caller's tenant and has no controllers (its creator drives it).
  absl::StatusOr<std::string> fork(const std::string& id, const std::string& tenant, const std::string& proposed_id,
                                   Clock::time_point deadline);
  std::vector<SessionInfo> list(const std::string& tenant);
  // Claims controlled agents without a controller for one client. With `credential` (one this session issued), the
  // agents are added to it; else a new credential (128 random bits) is made.
  absl::StatusOr<JoinResult> join(const std::string& id, const std::string& tenant,
                                  const std::vector<int64_t>& agent_ids, const std::string& credential);
  // Registers `w` for every tick of session `id` from the current one on (given to it before this returns), until
  // on_end() or w->done(). RESOURCE_EXHAUSTED beyond --max_watchers streams not yet done.
  absl::Status watch_add(const std::string& id, const std::string& tenant, std::shared_ptr<TickWatcher> w);
  // A stream registered by watch_add is over (its place under --max_watchers is free again). Takes no lock.
  void watch_done() { --watchers_; }
  int watchers() const { return watchers_; }
  // Engine calls waiting for a compute thread.
  int compute_queued() { return compute_.waiting(); }

  // Refuses new work and ends every watch stream.
  void start_draining();
  bool draining() const { return draining_; }
  // Saves every session to the snapshot directory (after the gRPC server stopped).
  int save_all();
  // Restores every snapshot of the snapshot directory; returns how many.
  int restore_all();
  int count();
  uint64_t total_bytes();

 private:
  // The session `id` of `tenant` (restored if it was evicted); NOT_FOUND alike for unknown ids and other tenants'.
  absl::StatusOr<std::shared_ptr<ManagedSession>> find(const std::string& id, const std::string& tenant,
                                                       Clock::time_point deadline);
  // Closes `id` if `tenant` is null or its tenant (the reaper closes any tenant's idle sessions).
  absl::Status close_impl(const std::string& id, const std::string* tenant);
  absl::StatusOr<std::string> new_id(const std::string& proposed);
  // Evicts idle sessions other than `keep` (LRU) until `extra_sessions` more sessions and `extra_bytes` more bytes
  // fit under the caps; RESOURCE_EXHAUSTED when they cannot. Holds mu_.
  absl::Status make_room_locked(uint64_t extra_bytes, int extra_sessions = 1, const ManagedSession* keep = nullptr);
  // Room under --max_cache_mb for one more tick of `s` (its largest growth so far), evicting idle sessions if needed.
  absl::Status room_to_grow(ManagedSession& s);
  absl::Status evict_locked(const std::shared_ptr<ManagedSession>& s);
  absl::Status save(ManagedSession& s);
  absl::StatusOr<std::shared_ptr<ManagedSession>> restore_snapshot(const std::string& id, Clock::time_point deadline);
  absl::StatusOr<std::shared_ptr<ManagedSession>> restore_from(Snapshot snap, Clock::time_point deadline);
  // Runs `fn` on a compute thread (compute_threads of them), or DEADLINE_EXCEEDED when none takes it in time.
  absl::Status compute(Clock::time_point deadline, const std::function<absl::Status()>& fn);
  // Runs n ticks, each a compute call of its own, appending each tick's view to `out`. Stops between ticks
  // (DEADLINE_EXCEEDED, CANCELLED) once the deadline passed or `cancelled()` says the client is gone.
  absl::Status run_ticks(ManagedSession& s, const std::vector<ControlInput>& controls, int n,
                         Clock::time_point deadline, const std::function<bool()>& cancelled,
                         std::vector<TickView>* out);
  // Saves every session that changed since its last snapshot (the background snapshots).
  void save_changed();
  bool evicted_contains(const std::string& id);
  // PERMISSION_DENIED when an agent of `agents` has a controller whose credential is not `credential`, or when
  // `credential` is set but not one this session issued. Holds s.mu.
  static absl::Status check_controller_locked(const ManagedSession& s, const std::string& credential,
                                              const std::vector<ControlInput>& agents, const char* field,
                                              const char* action);
  // Ends and drops the watchers of `s`. Holds s.mu.
  void end_watchers_locked(ManagedSession& s);
  // Closes idle sessions and writes the background snapshots.
  void reaper();

  Engine& engine_;
  ManagerOptions options_;
  Metrics& metrics_;
  std::mutex mu_;
  std::map<std::string, std::shared_ptr<ManagedSession>> sessions_;
  std::map<std::string, std::string> evicted_;  // id -> tenant: saved to the snapshot directory, restored on next call
  std::atomic<bool> draining_{false};
  std::atomic<int> watchers_{0};
  std::atomic<bool> stop_{false};
  std::atomic<int> closed_since_trim_{0};  // sessions closed or evicted since the reaper's last malloc_trim
  std::thread reaper_;
  ComputeQueue compute_;  // last: its threads stop first
};

}  // namespace ss::server
