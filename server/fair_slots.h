// A counting semaphore that hands free slots to waiters in arrival order. std::counting_semaphore has no order:
// under 32 clients on 2 compute threads it let some wait >10 s while others went straight through (measured p99
// 11.4 s against p50 35 ms); with FIFO hand-over every session advances evenly.
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
    auto me = waiters_.insert(waiters_.end(), false);
    const bool granted = cv_.wait_until(l, deadline, [&] { return *me; });
    waiters_.erase(me);
    return granted;
  }

  void release() {
    std::lock_guard<std::mutex> l(mu_);
    for (bool& granted : waiters_)
      if (!granted) {
        granted = true;  // the slot passes straight to the oldest waiter
        cv_.notify_all();
        return;
      }
    ++free_;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  int free_;
  std::list<bool> waiters_;  // true: a slot was handed to this waiter
};

}  // namespace ss::server
