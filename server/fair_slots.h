// A counting semaphore that hands free slots to waiters in arrival order. std::counting_semaphore has no order:
// under 32 clients on 2 compute threads it let some wait >10 s while others went straight through (measured p99
// 11.4 s against p50 35 ms); with FIFO hand-over every session advances evenly. Each waiter sleeps on its own
// condition variable, so a release wakes the one thread it hands the slot to, not all 30 that wait.
#pragma once

#include <chrono>
#include <condition_variable>
#include <list>
#include <mutex>

namespace ss::server {

class FairSlots {
 public:
  explicit FairSlots(int n) : free_(n) {}

  // False when `deadline` passed before a slot was handed over.
  bool acquire_until(std::chrono::steady_clock::time_point deadline) {
    std::unique_lock<std::mutex> l(mu_);
    if (free_ > 0 && waiters_.empty()) {
      --free_;
      return true;
    }
    auto me = waiters_.emplace(waiters_.end());
    const bool granted = me->cv.wait_until(l, deadline, [&] { return me->granted; });
    waiters_.erase(me);
    return granted;
  }

  void release() {
    std::lock_guard<std::mutex> l(mu_);
    for (Waiter& w : waiters_)
      if (!w.granted) {
        w.granted = true;  // the slot passes straight to the oldest waiter
        w.cv.notify_one();
        return;
      }
    ++free_;
  }

  // Threads waiting for a slot now.
  int waiting() {
    std::lock_guard<std::mutex> l(mu_);
    return static_cast<int>(waiters_.size());
  }

 private:
  struct Waiter {
    bool granted = false;  // a slot was handed to this waiter
    std::condition_variable cv;
  };
  std::mutex mu_;
  int free_;
  std::list<Waiter> waiters_;  // in arrival order
};

}  // namespace ss::server
