#include "server/clock.h"

namespace ss::server {
namespace {

class RealClock final : public Clock {
 public:
  TimePoint now() const override { return std::chrono::steady_clock::now(); }
  void wait_until(std::unique_lock<std::mutex>& l, std::condition_variable& cv, TimePoint until) const override {
    cv.wait_until(l, until);
  }
};

}  // namespace

const Clock& real_clock() {
  static const RealClock clock;
  return clock;
}

TestClock::TestClock() : now_(std::chrono::steady_clock::now()) {}

TimePoint TestClock::now() const {
  std::lock_guard<std::mutex> g(mu_);
  return now_;
}

void TestClock::wait_until(std::unique_lock<std::mutex>& l, std::condition_variable& cv, TimePoint until) const {
  {
    std::lock_guard<std::mutex> g(mu_);
    if (now_ >= until) return;
    waiting_.insert(&cv);
    ++waiters_;
    ++waits_;
  }
  waiters_changed_.notify_all();
  // advance() notifies `cv` without holding the waiter's mutex (taking it there would order the locks against the
  // waiter's), so a notify may fall between the check above and the wait: the short wall-time slice bounds that miss.
  // The caller's loop checks again either way.
  cv.wait_for(l, std::chrono::milliseconds(5));
  {
    std::lock_guard<std::mutex> g(mu_);
    waiting_.erase(waiting_.find(&cv));
    --waiters_;
  }
  waiters_changed_.notify_all();
}

void TestClock::advance(Duration d) {
  std::lock_guard<std::mutex> g(mu_);
  now_ += d;
  for (std::condition_variable* cv : waiting_) cv->notify_all();
}

int TestClock::waiters() const {
  std::lock_guard<std::mutex> g(mu_);
  return waiters_;
}

bool TestClock::await_waiters(int n, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> g(mu_);
  return waiters_changed_.wait_for(g, timeout, [&] { return waiters_ >= n; });
}

int64_t TestClock::waits() const {
  std::lock_guard<std::mutex> g(mu_);
  return waits_;
}

bool TestClock::await_waits(int64_t n, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> g(mu_);
  return waiters_changed_.wait_for(g, timeout, [&] { return waits_ >= n; });
}

}  // namespace ss::server
