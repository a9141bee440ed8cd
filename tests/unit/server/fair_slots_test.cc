// FairSlots (server/fair_slots.h): slots go to waiters in arrival order, a waiter whose deadline passes gives up
// without taking a slot, and no slot is lost or doubled under many threads.
#include "server/fair_slots.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

namespace ss::server {
namespace {

using Clock = std::chrono::steady_clock;

void wait_for_waiters(FairSlots& s, int n) {
  const auto give_up = Clock::now() + std::chrono::seconds(10);
  while (s.waiting() < n && Clock::now() < give_up) std::this_thread::yield();
  ASSERT_EQ(s.waiting(), n);
}

TEST(FairSlots, FreeSlotsAreTakenAtOnceAndThenTheDeadlineDecides) {
  FairSlots s(2);
  const auto now = Clock::now();
  EXPECT_TRUE(s.acquire_until(now));
  EXPECT_TRUE(s.acquire_until(now));
  EXPECT_FALSE(s.acquire_until(Clock::now() + std::chrono::milliseconds(20)));
  EXPECT_EQ(s.waiting(), 0);
  s.release();
  EXPECT_TRUE(s.acquire_until(Clock::now()));
}

TEST(FairSlots, WaitersAreServedInArrivalOrder) {
  FairSlots s(1);
  ASSERT_TRUE(s.acquire_until(Clock::now()));
  constexpr int kWaiters = 8;
  std::vector<int> order;
  std::mutex order_mu;
  std::vector<std::thread> threads;
  for (int i = 0; i < kWaiters; ++i) {
    threads.emplace_back([&, i] {
      ASSERT_TRUE(s.acquire_until(Clock::now() + std::chrono::seconds(30)));
      {
        std::lock_guard<std::mutex> l(order_mu);
        order.push_back(i);
      }
      s.release();
    });
    wait_for_waiters(s, i + 1);  // thread i waits before thread i + 1 starts
  }
  s.release();
  for (std::thread& t : threads) t.join();
  std::vector<int> want(kWaiters);
  for (int i = 0; i < kWaiters; ++i) want[i] = i;
  EXPECT_EQ(order, want);
}

TEST(FairSlots, AWaiterThatGivesUpLeavesTheSlotToTheNext) {
  FairSlots s(1);
  ASSERT_TRUE(s.acquire_until(Clock::now()));
  std::atomic<bool> late_got{false};
  // A second, so that `late` is surely waiting behind it before it gives up, even on a loaded machine.
  std::thread early([&] { EXPECT_FALSE(s.acquire_until(Clock::now() + std::chrono::seconds(1))); });
  wait_for_waiters(s, 1);
  std::thread late([&] {
    late_got = s.acquire_until(Clock::now() + std::chrono::seconds(30));
    if (late_got) s.release();
  });
  wait_for_waiters(s, 2);
  early.join();  // its deadline passes while the slot is held
  s.release();   // goes to `late`
  late.join();
  EXPECT_TRUE(late_got);
  EXPECT_TRUE(s.acquire_until(Clock::now()));  // and came back
}

TEST(FairSlots, ManyThreadsNeverHoldMoreSlotsThanThereAre) {
  constexpr int kSlots = 2, kThreads = 16, kRounds = 300;
  FairSlots s(kSlots);
  std::atomic<int> inside{0}, most{0}, done{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i)
    threads.emplace_back([&] {
      for (int r = 0; r < kRounds; ++r) {
        if (!s.acquire_until(Clock::now() + std::chrono::seconds(30))) continue;
        const int now = ++inside;
        for (int m = most; now > m && !most.compare_exchange_weak(m, now);) {
        }
        --inside;
        ++done;
        s.release();
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(done, kThreads * kRounds);
  EXPECT_LE(most, kSlots);
  EXPECT_EQ(s.waiting(), 0);
  for (int i = 0; i < kSlots; ++i) EXPECT_TRUE(s.acquire_until(Clock::now()));  // every slot came back
  EXPECT_FALSE(s.acquire_until(Clock::now()));
}

}  // namespace
}  // namespace ss::server
