// The one thread pool (engine/base/thread_pool.h). run(), as the server's compute threads use it: calls run on the
// pool's threads in arrival order, a call whose deadline passes while queued is not run, a started call runs to its
// end, a throw becomes INTERNAL, and no more calls run at once than there are threads. parallel_for(), as a decode
// call shares its attention: every task once, on the caller and the threads, the caller alone when they are busy.
#include "engine/base/thread_pool.h"

#include <gtest/gtest.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace ss {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kLong = std::chrono::seconds(30);

void wait_for_queued(ThreadPool& q, int n) {
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

TEST(ThreadPool, CallsRunOnItsThreadsAfterTheirInitAndReturnTheirStatus) {
  std::mutex mu;
  std::vector<std::thread::id> initialised;
  ThreadPool q(2, [&] {
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

TEST(ThreadPool, CallsRunInArrivalOrder) {
  ThreadPool q(1);
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

TEST(ThreadPool, AQueuedCallWhoseDeadlinePassesIsNotRunAndTheNextIs) {
  ThreadPool q(1);
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

TEST(ThreadPool, AStartedCallRunsToItsEndPastItsDeadline) {
  ThreadPool q(1);
  Gate gate;
  const auto deadline = Clock::now() + std::chrono::milliseconds(20);
  absl::Status st = absl::UnknownError("not run");
  std::thread call([&] { st = q.run(deadline, [&] { return gate.hold(); }); });
  gate.wait_entered();
  while (Clock::now() <= deadline) std::this_thread::yield();  // the call is running when its deadline passes
  gate.open();
  call.join();
  EXPECT_TRUE(st.ok()) << st;
}

TEST(ThreadPool, AThrowIsAnInternalErrorAndTheThreadGoesOn) {
  ThreadPool q(1);
  const absl::Status st = q.run(Clock::now() + kLong, []() -> absl::Status { throw std::runtime_error("no memory"); });
  EXPECT_EQ(st.code(), absl::StatusCode::kInternal);
  EXPECT_NE(st.message().find("no memory"), std::string::npos) << st;
  EXPECT_TRUE(q.run(Clock::now() + kLong, [] { return absl::OkStatus(); }).ok());
}

TEST(ThreadPool, ManyCallersNeverRunMoreCallsAtOnceThanThreads) {
  constexpr int kThreads = 2, kCallers = 16, kRounds = 300;
  ThreadPool q(kThreads);
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

TEST(ThreadPool, WithoutThreadsACallRunsOnTheCaller) {
  ThreadPool q(0);
  std::thread::id ran_on;
  EXPECT_TRUE(q.run(Clock::now() + kLong, [&] {
                 ran_on = std::this_thread::get_id();
                 return absl::OkStatus();
               }).ok());
  EXPECT_EQ(ran_on, std::this_thread::get_id());
}

// Runs `tasks` tasks and checks each ran exactly once, with a thread index the pool names.
void expect_each_task_once(ThreadPool& pool, int tasks) {
  std::vector<std::atomic<int>> runs(tasks);
  std::atomic<int> bad_thread{0};
  pool.parallel_for(tasks, [&](int task, int thread) {
    runs[task].fetch_add(1);
    if (thread < 0 || thread > pool.threads()) bad_thread.fetch_add(1);
  });
  for (int i = 0; i < tasks; ++i) ASSERT_EQ(runs[i].load(), 1) << "task " << i << " of " << tasks;
  EXPECT_EQ(bad_thread.load(), 0);
}

TEST(ThreadPool, ParallelForRunsEveryTaskOnce) {
  for (int threads : {0, 1, 3}) {
    ThreadPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (int tasks : {0, 1, 2, 7, 1000}) expect_each_task_once(pool, tasks);
  }
}

TEST(ThreadPool, ParallelForSharesTheTasksWithTheThreads) {
  ThreadPool pool(1);
  // Each task waits until both have started, so the call finishes only if the pool's thread joins in.
  std::atomic<int> started{0};
  std::vector<int> thread_of(2, -1);
  pool.parallel_for(2, [&](int task, int thread) {
    thread_of[task] = thread;
    started.fetch_add(1);
    while (started.load() < 2) std::this_thread::yield();
  });
  EXPECT_NE(thread_of[0], thread_of[1]);
}

TEST(ThreadPool, ParallelForRunsOnTheCallerAloneWhenTheThreadsAreBusy) {
  ThreadPool pool(1);
  Gate gate;
  std::thread busy([&] { EXPECT_TRUE(pool.run(Clock::now() + kLong, [&] { return gate.hold(); }).ok()); });
  gate.wait_entered();
  std::vector<int> thread_of(50, -1);
  pool.parallel_for(50, [&](int task, int thread) { thread_of[task] = thread; });  // returns with the thread held
  EXPECT_EQ(thread_of, std::vector<int>(50, 0));
  EXPECT_EQ(pool.waiting(), 0) << "the helper that never started was taken back";
  gate.open();
  busy.join();
}

TEST(ThreadPool, ParallelForCallersAtOnceEachFinishTheirOwnTasks) {
  ThreadPool pool(1);
  std::vector<std::thread> callers;
  std::atomic<int> failures{0};
  for (int c = 0; c < 4; ++c)
    callers.emplace_back([&, c] {
      for (int round = 0; round < 50; ++round) {
        const int tasks = 10 + c;
        std::vector<std::atomic<int>> runs(tasks);
        pool.parallel_for(tasks, [&](int task, int) { runs[task].fetch_add(1); });
        for (auto& r : runs)
          if (r.load() != 1) failures.fetch_add(1);
      }
    });
  for (auto& t : callers) t.join();
  EXPECT_EQ(failures.load(), 0);
}

TEST(ThreadPool, ParallelForTasksRunWithTheCallersFloatModes) {
  ThreadPool pool(2);
  const unsigned before = _mm_getcsr();
  _mm_setcsr(before | 0x8040);  // flush-to-zero and denormals-are-zero
  std::vector<unsigned> csr(64);
  std::atomic<int> started{0};
  pool.parallel_for(64, [&](int task, int) {
    // The first tasks wait for each other, so the pool's threads surely run some.
    if (started.fetch_add(1) < 3) while (started.load() < 3) std::this_thread::yield();
    csr[task] = _mm_getcsr() & 0x8040;
  });
  _mm_setcsr(before);
  EXPECT_EQ(csr, std::vector<unsigned>(64, 0x8040u));
}

TEST(ThreadPool, SubmittedJobsRunAndTheDestructorWaitsForThem) {
  std::atomic<int> ran{0};
  {
    ThreadPool pool(2);
    for (int i = 0; i < 100; ++i) pool.submit([&] { ++ran; });
  }
  EXPECT_EQ(ran.load(), 100);
}

}  // namespace
}  // namespace ss
