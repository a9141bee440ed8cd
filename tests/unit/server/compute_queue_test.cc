// ComputeQueue (server/compute_queue.h): calls run on its own threads in arrival order, a call whose deadline passes
// while queued is not run, a started call runs to its end, a throw becomes INTERNAL, and no more calls run at once
// than there are threads.
#include "server/compute_queue.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace ss::server {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kLong = std::chrono::seconds(30);

void wait_for_queued(ComputeQueue& q, int n) {
  const auto give_up = Clock::now() + std::chrono::seconds(10);
  while (q.waiting() < n && Clock::now() < give_up) std::this_thread::yield();
  ASSERT_EQ(q.waiting(), n);
}

// Holds the queue's one thread until open() is called, so that the calls behind it queue up.
struct Gate {
  std::mutex mu;
  std::condition_variable cv;
  bool open_ = false, entered = false;
  absl::Status hold() {
    std::unique_lock<std::mutex> l(mu);
    entered = true;
    cv.notify_all();
    cv.wait(l, [&] { return open_; });
    return absl::OkStatus();
  }
  void wait_entered() {
    std::unique_lock<std::mutex> l(mu);
    cv.wait(l, [&] { return entered; });
  }
  void open() {
    std::lock_guard<std::mutex> l(mu);
    open_ = true;
    cv.notify_all();
  }
};

TEST(ComputeQueue, CallsRunOnItsThreadsAfterTheirInitAndReturnTheirStatus) {
  std::mutex mu;
  std::vector<std::thread::id> initialised;
  ComputeQueue q(2, [&] {
    std::lock_guard<std::mutex> l(mu);
    initialised.push_back(std::this_thread::get_id());
  });
  std::thread::id ran_on;
  const absl::Status st = q.run(Clock::now() + kLong, [&] {
    ran_on = std::this_thread::get_id();
    return absl::NotFoundError("from the call");
  });
  EXPECT_EQ(st, absl::NotFoundError("from the call"));
  EXPECT_NE(ran_on, std::this_thread::get_id());
  {
    std::lock_guard<std::mutex> l(mu);  // the thread that ran the call had run its init
    EXPECT_NE(std::find(initialised.begin(), initialised.end(), ran_on), initialised.end());
  }
  const auto give_up = Clock::now() + std::chrono::seconds(10);  // the other thread may start later
  for (;;) {
    {
      std::lock_guard<std::mutex> l(mu);
      if (initialised.size() == 2 || Clock::now() > give_up) break;
    }
    std::this_thread::yield();
  }
  std::lock_guard<std::mutex> l(mu);
  EXPECT_EQ(initialised.size(), 2u);
}

TEST(ComputeQueue, CallsRunInArrivalOrder) {
  ComputeQueue q(1, nullptr);
  Gate gate;
  std::thread first([&] { EXPECT_TRUE(q.run(Clock::now() + kLong, [&] { return gate.hold(); }).ok()); });
  gate.wait_entered();
  constexpr int kCalls = 8;
  std::vector<int> order;  // written by the queue's one thread only
  std::vector<std::thread> callers;
  for (int i = 0; i < kCalls; ++i) {
    callers.emplace_back([&, i] {
      EXPECT_TRUE(q.run(Clock::now() + kLong, [&, i] {
                     order.push_back(i);
                     return absl::OkStatus();
                   }).ok());
    });
    wait_for_queued(q, i + 1);  // call i is queued before call i + 1 is made
  }
  gate.open();
  first.join();
  for (std::thread& t : callers) t.join();
  std::vector<int> want(kCalls);
  for (int i = 0; i < kCalls; ++i) want[i] = i;
  EXPECT_EQ(order, want);
}

TEST(ComputeQueue, AQueuedCallWhoseDeadlinePassesIsNotRunAndTheNextIs) {
  ComputeQueue q(1, nullptr);
  Gate gate;
  std::thread first([&] { EXPECT_TRUE(q.run(Clock::now() + kLong, [&] { return gate.hold(); }).ok()); });
  gate.wait_entered();
  std::atomic<bool> early_ran{false}, late_ran{false};
  // A second, so that `late` is surely queued behind it before it gives up, even on a loaded machine.
  std::thread early([&] {
    const absl::Status st = q.run(Clock::now() + std::chrono::seconds(1), [&] {
      early_ran = true;
      return absl::OkStatus();
    });
    EXPECT_EQ(st.code(), absl::StatusCode::kDeadlineExceeded) << st;
  });
  wait_for_queued(q, 1);
  std::thread late([&] {
    EXPECT_TRUE(q.run(Clock::now() + kLong, [&] {
                   late_ran = true;
                   return absl::OkStatus();
                 }).ok());
  });
  wait_for_queued(q, 2);
  early.join();  // its deadline passed while the thread was held
  EXPECT_EQ(q.waiting(), 1);
  gate.open();
  first.join();
  late.join();
  EXPECT_FALSE(early_ran);
  EXPECT_TRUE(late_ran);
}

TEST(ComputeQueue, AStartedCallRunsToItsEndPastItsDeadline) {
  ComputeQueue q(1, nullptr);
  const absl::Status st = q.run(Clock::now() + std::chrono::milliseconds(20), [] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    return absl::OkStatus();
  });
  EXPECT_TRUE(st.ok()) << st;
}

TEST(ComputeQueue, AThrowIsAnInternalErrorAndTheThreadGoesOn) {
  ComputeQueue q(1, nullptr);
  const absl::Status st = q.run(Clock::now() + kLong, []() -> absl::Status { throw std::runtime_error("no memory"); });
  EXPECT_EQ(st.code(), absl::StatusCode::kInternal);
  EXPECT_NE(st.message().find("no memory"), std::string::npos) << st;
  EXPECT_TRUE(q.run(Clock::now() + kLong, [] { return absl::OkStatus(); }).ok());
}

TEST(ComputeQueue, ManyCallersNeverRunMoreCallsAtOnceThanThreads) {
  constexpr int kThreads = 2, kCallers = 16, kRounds = 300;
  ComputeQueue q(kThreads, nullptr);
  std::atomic<int> inside{0}, most{0}, done{0};
  std::vector<std::thread> callers;
  for (int i = 0; i < kCallers; ++i)
    callers.emplace_back([&] {
      for (int r = 0; r < kRounds; ++r) {
        const absl::Status st = q.run(Clock::now() + kLong, [&] {
          const int now = ++inside;
          for (int m = most; now > m && !most.compare_exchange_weak(m, now);) {
          }
          --inside;
          ++done;
          return absl::OkStatus();
        });
        EXPECT_TRUE(st.ok()) << st;
      }
    });
  for (std::thread& t : callers) t.join();
  EXPECT_EQ(done, kCallers * kRounds);
  EXPECT_LE(most, kThreads);
  EXPECT_EQ(q.waiting(), 0);
}

}  // namespace
}  // namespace ss::server
