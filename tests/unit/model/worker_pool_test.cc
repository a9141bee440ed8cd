// The pool that shares one decode call's attention groups between threads.
#include "engine/model/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

namespace ss {
namespace {

// Runs `tasks` tasks and checks each ran exactly once, on a thread index the pool names.
void expect_each_task_once(WorkerPool& pool, int tasks) {
  std::vector<std::atomic<int>> runs(tasks);
  std::atomic<int> bad_thread{0};
  pool.parallel_for(tasks, [&](int task, int thread) {
    runs[task].fetch_add(1);
    if (thread < 0 || thread >= pool.threads()) bad_thread.fetch_add(1);
  });
  for (int i = 0; i < tasks; ++i) ASSERT_EQ(runs[i].load(), 1) << "task " << i << " of " << tasks;
  EXPECT_EQ(bad_thread.load(), 0);
}

TEST(WorkerPool, EveryTaskRunsOnce) {
  for (int threads : {1, 2, 4}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (int tasks : {0, 1, 2, 7, 1000}) expect_each_task_once(pool, tasks);
  }
  EXPECT_EQ(WorkerPool(0).threads(), 1);
}

TEST(WorkerPool, TheWorkersShareTheTasks) {
  WorkerPool pool(2);
  // Each task waits until both threads have started one, so the call finishes only if the worker joins in.
  std::atomic<int> started{0};
  std::vector<int> thread_of(2, -1);
  pool.parallel_for(2, [&](int task, int thread) {
    thread_of[task] = thread;
    started.fetch_add(1);
    while (started.load() < 2) std::this_thread::yield();
  });
  EXPECT_NE(thread_of[0], thread_of[1]);
}

TEST(WorkerPool, CallersAtOnceEachFinishTheirOwnTasks) {
  WorkerPool pool(2);
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

}  // namespace
}  // namespace ss
