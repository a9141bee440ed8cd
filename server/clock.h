// The session manager's time: idle timeouts, eviction age, snapshot and trim intervals, tick and call deadlines, the
// reaper's pace. Behind an interface so that tests drive it (TestClock) instead of sleeping on wall time and asserting
// on how long a wait took. Time points are on the steady clock's timeline either way, so a deadline a gRPC handler
// computes from the real clock and one a test computes from its own clock have the same type. One wait is on the real
// clock whatever this one says: a call's wait for a compute thread (ThreadPool::run), which is real work progressing.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <set>

namespace ss::server {

using TimePoint = std::chrono::steady_clock::time_point;
using Duration = std::chrono::steady_clock::duration;

class Clock {
 public:
  virtual ~Clock() = default;
  virtual TimePoint now() const = 0;
  // Waits on `cv` (whose mutex `l` holds) until it is notified or the clock reaches `until`. May return early
  // (spuriously): callers wait in a loop that checks their condition and the time.
  virtual void wait_until(std::unique_lock<std::mutex>& l, std::condition_variable& cv, TimePoint until) const = 0;
};

// std::chrono::steady_clock, for the server.
const Clock& real_clock();

// A clock that moves only when a test advances it. A wait on it returns once advance() passed its time point (or on a
// notify). Tests find out that a call is waiting through waiters() / await_waiters(), a condition rather than a sleep.
class TestClock final : public Clock {
 public:
  // Starts at the real clock's now, so deadlines from either clock are comparable at the start of a test.
  TestClock();
  TimePoint now() const override;
  void wait_until(std::unique_lock<std::mutex>& l, std::condition_variable& cv, TimePoint until) const override;

  // Moves the time forward and wakes every wait.
  void advance(Duration d);
  // Threads waiting on the clock now.
  int waiters() const;
  // Blocks until at least `n` threads wait on the clock; false if that did not happen within `timeout` of wall time
  // (a test's safety net against a hang, not a pace).
  bool await_waiters(int n, std::chrono::milliseconds timeout = std::chrono::seconds(60)) const;
  // Waits begun so far. A wait counted after advance() returned saw the new time: await_waits(waits() + 1) after an
  // advance is how a test knows that a waiting call looked at the new time and went on waiting.
  int64_t waits() const;
  bool await_waits(int64_t n, std::chrono::milliseconds timeout = std::chrono::seconds(60)) const;

 private:
  mutable std::mutex mu_;
  mutable std::condition_variable waiters_changed_;
  TimePoint now_;
  mutable std::multiset<std::condition_variable*> waiting_;  // the cvs that wait_until() blocks on, to notify on advance
  mutable int waiters_ = 0;
  mutable int64_t waits_ = 0;
};

}  // namespace ss::server
