// One hosted session as the session manager's parts share it: the registry (server/session_registry.h) holds it, the
// tick barrier (server/tick_barrier.h) and the watchers (server/watch_hub.h) work on it.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>

#include "absl/status/status.h"
#include "engine/scenestreamer.h"
#include "server/clock.h"
#include "server/watch_hub.h"

namespace ss::server {

class SessionStore;  // server/session_store.h

struct ManagerOptions {
  std::string snapshot_dir;          // empty: no snapshots, and no eviction (nowhere to keep an evicted session)
  double snapshot_interval_s = 30;   // a changed session is saved at least this often, busy or idle (0: only on
                                     // eviction and SIGTERM)
  int max_sessions = 256;
  uint64_t max_cache_bytes = uint64_t{8} << 30;
  // One tenant's share of the caps (server/auth.h: a tenant is a token's owner); 0: the whole cap.
  int tenant_max_sessions = 0;
  uint64_t tenant_max_cache_bytes = 0;
  double idle_timeout_s = 3600;      // a session unused this long is closed
  double evict_idle_s = 30;          // a session unused this long may be evicted (LRU) to make room
  int compute_threads = 2;           // engine calls running at once
  int default_tick_deadline_ms = 2000;
  int max_watchers = 1024;           // WatchSession streams open at once, over all sessions
  // Once sessions closed (or were evicted), at most this often: an allocator purge from the reaper thread, so what
  // they freed leaves the resident set now rather than at jemalloc's decay (server/allocator.h). 0: never.
  double malloc_trim_interval_s = 0;
  // Idle timeouts, intervals, deadlines and the reaper's pace read this clock; null: the real one. Not owned.
  const Clock* clock = nullptr;
  // The shared session store (server/session_store.h) instead of snapshot_dir: snapshots go there, under a lease per
  // session. Not owned; null: none.
  SessionStore* session_store = nullptr;
  // False: no reaper thread; the owner calls SessionManager::reap() (tests, with a TestClock, one pass at a time).
  bool reaper_thread = true;
};

// The multi-client tick's state (server/tick_barrier.h). Guarded by ManagedSession::mu.
struct BarrierState {
  std::map<int64_t, ControlInput> pending;  // poses for tick + 1
  std::optional<TimePoint> pending_since;   // when the first of them came: the tick deadline counts from there
  bool stepping = false;                    // a caller is computing the tick
  int64_t failed_tick = -1;                 // the last tick whose computation failed, and why
  absl::Status failed_status;
};

// `engine_mu` serialises engine calls on `session`; `mu` guards the tick clock, the barrier, the recent ticks and the
// watchers (held only briefly, never across an engine call).
struct ManagedSession {
  explicit ManagedSession(const Clock& c) : clock(c) {}

  const Clock& clock;
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
  TimePoint saved_at;                            // when it was last written, or created (under engine_mu)
  std::atomic<int64_t> last_used{0};             // the clock's time since its epoch, nanoseconds
  std::atomic<int> calls{0};                     // calls in progress: waiting (a slot, other controllers) or running

  std::mutex mu;
  std::condition_variable cv;
  int64_t tick = 0;
  StepResult view;                               // the current tick as GetSession shows it (no events)
  std::set<int64_t> controllers;                 // controlled agents alive: each may have its own client
  std::map<int64_t, std::string> controller_of;  // agent -> its controller's credential's SHA-256 (JoinSession)
  BarrierState barrier;
  std::deque<TickView> recent;                   // the last ticks, for waiting controllers
  SessionWatchers watchers;                      // WatchSession streams
  bool closed = false;
  // Handed over to another replica (the shared session store): set under engine_mu, so a call that takes engine_mu
  // after it never computes on this copy.
  std::atomic<bool> moved{false};

  void touch() { last_used = std::chrono::nanoseconds(clock.now().time_since_epoch()).count(); }
  // 0 while a call is in progress: a call that waits (for a compute thread under load, or for the other controllers
  // of a multi-client tick) must not have its session closed or evicted under it by the idle rules.
  double idle_seconds() const {
    if (calls > 0) return 0;
    return std::chrono::duration<double>(clock.now().time_since_epoch() - std::chrono::nanoseconds(last_used.load()))
        .count();
  }
  // The session's tick `tick` is now `v`: the view, the controllers alive, the recent ticks, the watchers. Holds mu.
  void publish(const StepResult& v) {
    view = v;
    view.events.clear();  // events belong to the tick a call made (StepScene, watchers), not to the current view
    controllers.clear();
    for (const AgentView& a : v.agents)
      if (a.controlled) controllers.insert(a.id);
    recent.push_back({tick, v});
    while (recent.size() > 64) recent.pop_front();
    watchers.publish(recent.back());
  }
  // For a call that holds engine_mu: UNAVAILABLE once the session moved to another replica (the retry reaches it).
  absl::Status check_not_moved() const {
    if (!moved) return absl::OkStatus();
    return absl::UnavailableError("session '" + id +
                                  "' moved to another replica while this call waited; retry the call");
  }
  // Marks the session closed: waiting controllers wake, watchers end. Holds mu.
  void close_locked() {
    closed = true;
    cv.notify_all();
    watchers.end();
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

}  // namespace ss::server
