// The test clock the session manager's tests drive: a wait returns when the clock is advanced past its time, not
// before, and a test can tell that a thread waits.
#include "server/clock.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

namespace ss::server {
namespace {

TEST(TestClock, MovesOnlyWhenAdvanced) {
  TestClock clock;
  const TimePoint t0 = clock.now();
  EXPECT_EQ(clock.now(), t0);
  clock.advance(std::chrono::seconds(3));
  EXPECT_EQ(clock.now() - t0, std::chrono::seconds(3));
}

TEST(TestClock, AWaitEndsOnceTheClockPassesItsTime) {
  TestClock clock;
  std::mutex mu;
  std::condition_variable cv;
  const TimePoint until = clock.now() + std::chrono::seconds(10);
  std::atomic<bool> done{false};
  std::thread waiter([&] {
    std::unique_lock<std::mutex> l(mu);
    while (clock.now() < until) clock.wait_until(l, cv, until);
    done = true;
  });
  ASSERT_TRUE(clock.await_waiters(1));
  clock.advance(std::chrono::seconds(9));
  ASSERT_TRUE(clock.await_waits(clock.waits() + 1));  // it saw 9 s and waits on
  EXPECT_FALSE(done);
  clock.advance(std::chrono::seconds(1));
  waiter.join();
  EXPECT_TRUE(done);
  EXPECT_EQ(clock.waiters(), 0);
}

TEST(TestClock, AWaitForATimePassedReturnsAtOnce) {
  TestClock clock;
  std::mutex mu;
  std::condition_variable cv;
  std::unique_lock<std::mutex> l(mu);
  clock.wait_until(l, cv, clock.now());
  EXPECT_EQ(clock.waits(), 0);
}

TEST(RealClock, IsTheSteadyClock) {
  const TimePoint before = std::chrono::steady_clock::now();
  const TimePoint t = real_clock().now();
  EXPECT_GE(t, before);
  EXPECT_LE(t, std::chrono::steady_clock::now());
}

}  // namespace
}  // namespace ss::server
