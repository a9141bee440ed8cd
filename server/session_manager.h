// The server's sessions as the gRPC handlers call them. It decides *when* an engine call runs and on which session;
// what a step does is the engine's (engine/scenestreamer.h). Its parts: the registry (ids, caps, eviction, snapshots,
// the reaper: server/session_registry.h), the tick barrier of multi-client sessions (server/tick_barrier.h), the watch
// streams (server/watch_hub.h), the compute threads (engine calls in arrival order, on the engine's ThreadPool), and a clock that tests drive
// (server/clock.h).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/scenestreamer.h"
#include "server/clock.h"
#include "server/managed_session.h"
#include "server/metrics.h"
#include "server/session_registry.h"
#include "server/watch_hub.h"

namespace ss::server {

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
                                  TimePoint deadline, std::string* id, std::vector<MapFeature>* map = nullptr);
  // One call's ticks. In a multi-client session the caller waits for the other controllers (or the tick deadline).
  // `credential`: JoinSession's, for agents with a controller (PERMISSION_DENIED for their poses without it).
  absl::StatusOr<std::vector<TickView>> step(const std::string& id, const std::string& tenant,
                                             const std::string& credential, const std::vector<ControlInput>& controls,
                                             int num_ticks, TimePoint deadline,
                                             const std::function<bool()>& cancelled = {});
  absl::StatusOr<std::vector<int64_t>> inject(const std::string& id, const std::string& tenant, const InjectRequest& r,
                                              TimePoint deadline);
  absl::Status state_force(const std::string& id, const std::string& tenant, const std::string& credential,
                           const StateForceRequest& r);
  absl::Status close(const std::string& id, const std::string& tenant) { return registry_.close(id, &tenant); }
  absl::StatusOr<std::pair<SessionInfo, TickView>> get(const std::string& id, const std::string& tenant);
  // The fork belongs to the caller's tenant and has no controllers (its creator drives it).
  absl::StatusOr<std::string> fork(const std::string& id, const std::string& tenant, const std::string& proposed_id,
                                   TimePoint deadline);
  std::vector<SessionInfo> list(const std::string& tenant);
  // Claims controlled agents without a controller for one client. With `credential` (one this session issued), the
  // agents are added to it; else a new credential (128 random bits) is made.
  absl::StatusOr<JoinResult> join(const std::string& id, const std::string& tenant,
                                  const std::vector<int64_t>& agent_ids, const std::string& credential);
  // Registers `w` for every tick of session `id` from the current one on (given to it before this returns), until
  // on_end() or w->done(). RESOURCE_EXHAUSTED beyond --max_watchers streams not yet done.
  absl::Status watch_add(const std::string& id, const std::string& tenant, std::shared_ptr<TickWatcher> w);
  // A stream registered by watch_add is over (its place under --max_watchers is free again). Takes no lock.
  void watch_done() { watch_hub_.release(); }
  int watchers() const { return watch_hub_.open(); }
  // Engine calls waiting for a compute thread.
  int compute_queued() { return compute_.waiting(); }

  // Refuses new work and ends every watch stream.
  void start_draining() { registry_.start_draining(); }
  bool draining() const { return registry_.draining(); }
  // Saves every session to the snapshot directory (after the gRPC server stopped).
  int save_all() { return registry_.save_all(); }
  // Restores every snapshot of the snapshot directory; returns how many.
  int restore_all() { return registry_.restore_all(); }
  int count() { return registry_.count(); }
  uint64_t total_bytes() { return registry_.total_bytes(); }
  // One pass of the reaper (idle closes, background snapshots, allocator purge), for ManagerOptions::reaper_thread
  // false.
  void reap() { registry_.reap(); }
  const Clock& clock() const { return clock_; }

 private:
  absl::Status compute(TimePoint deadline, const std::function<absl::Status()>& fn) {
    return compute_.run(deadline, fn);
  }
  // Runs n ticks, each a compute call of its own, appending each tick's view to `out`. Stops between ticks
  // (DEADLINE_EXCEEDED, CANCELLED) once the deadline passed or `cancelled()` says the client is gone.
  absl::Status run_ticks(ManagedSession& s, const std::vector<ControlInput>& controls, int n, TimePoint deadline,
                         const std::function<bool()>& cancelled, std::vector<TickView>* out);
  // PERMISSION_DENIED when an agent of `agents` has a controller whose credential is not `credential`, or when
  // `credential` is set but not one this session issued. Holds s.mu.
  static absl::Status check_controller_locked(const ManagedSession& s, const std::string& credential,
                                              const std::vector<ControlInput>& agents, const char* field,
                                              const char* action);

  Engine& engine_;
  const ManagerOptions options_;
  Metrics& metrics_;
  const Clock& clock_;
  WatchHub watch_hub_;
  // --threads compute threads: engine calls run there in arrival order. Before the registry: the registry's reaper,
  // stopped first, uses it.
  ThreadPool compute_;
  SessionRegistry registry_;
};

}  // namespace ss::server
