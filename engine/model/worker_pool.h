// Threads that share the independent parts of one decode call (attention over each key set) with the calling thread.
// A pool belongs to a Model and may be called from many sessions at once: a call that finds the workers busy runs
// all its tasks itself, so it never waits for another session's work. Every task computes the same bits whichever
// thread runs it, so results do not depend on the thread count.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace ss {

class WorkerPool {
 public:
  // `threads` - 1 workers (the caller is the other thread); at least 1.
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }
  // Calls fn(task, thread) for every task in [0, tasks), `thread` in [0, threads()) naming the scratch the task may
  // use (no two tasks run on one thread at once). Returns when every task is done.
  void parallel_for(int tasks, const std::function<void(int task, int thread)>& fn);

 private:
  void work(int thread);
  void run_tasks(int thread);

  std::vector<std::thread> workers_;
  std::mutex busy_;                  // held by the one call the workers serve
  std::mutex m_;
  std::condition_variable wake_, done_;
  uint64_t generation_ = 0;          // bumped per call the workers join
  int active_ = 0;                   // workers still on the current call
  bool stop_ = false;
  const std::function<void(int, int)>* fn_ = nullptr;
  unsigned csr_ = 0;                 // the caller's MXCSR (rounding, flush-to-zero), taken by the workers
  int tasks_ = 0;
  std::atomic<int> next_{0};         // the next task to take
};

}  // namespace ss
