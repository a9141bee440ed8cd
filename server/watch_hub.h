// WatchSession streams: the watchers of each session, fed every tick as it is computed, and the server-wide cap on
// streams open at once (--max_watchers). A watcher has no thread of its own (once 3000 streams held 3015 threads).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/status.h"
#include "engine/scenestreamer.h"

namespace ss::server {

struct TickView {
  int64_t tick = 0;
  StepResult view;
};

// Receives one session's ticks as they are computed (a WatchSession stream). It is called with the session's lock
// held, so it must not block or call the session manager back; it may call gRPC (whose reactions may run inline, so
// the watcher's own lock must allow that).
class TickWatcher {
 public:
  virtual ~TickWatcher() = default;
  // A tick, the current one first.
  virtual void on_tick(const TickView& t) = 0;
  // No more ticks: the session closed or was evicted, or the server drains.
  virtual void on_end() = 0;
  // True once the stream is over (it is then dropped).
  virtual bool done() const = 0;
};

// One session's watchers. Guarded by the session's lock (ManagedSession::mu).
class SessionWatchers {
 public:
  void add(std::shared_ptr<TickWatcher> w, const TickView& current);
  // Drops the watchers that are done, then gives `t` to the others.
  void publish(const TickView& t);
  // Ends and drops every watcher.
  void end();

 private:
  std::vector<std::shared_ptr<TickWatcher>> watchers_;
};

// The count of streams not yet done, over all sessions.
class WatchHub {
 public:
  explicit WatchHub(int max_watchers) : max_(max_watchers) {}
  // Takes a place for one more stream: RESOURCE_EXHAUSTED beyond --max_watchers.
  absl::Status reserve();
  // A reserved place that was not used, or a stream that is over (its place is free again). Takes no lock.
  void release() { --open_; }
  int open() const { return open_; }

 private:
  const int max_;
  std::atomic<int> open_{0};
};

}  // namespace ss::server
