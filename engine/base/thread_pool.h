// The project's one thread pool: a fixed set of threads taking jobs from one queue in arrival order. Three uses sit on
// it, each keeping the guarantees it had with a pool of its own:
// - run(): an engine call on a compute thread, the asking thread waiting for its status, with a deadline for the
//   wait in the queue (the server's compute threads: TF Serving's batch scheduler and llama.cpp's server loop run
//   theirs this way). In arrival order: an unordered semaphore once let some sessions wait >10 s under 32 clients
//   while others went straight through (p99 11.4 s against p50 35 ms). A thread takes the next call as soon as it
//   finishes one, without sleeping, and keeps its scratch warm: with each gRPC thread running its own calls under a
//   semaphore, the 2 cores sat idle 7 % of the time under 32 clients.
// - parallel_for(): the independent parts of one decode call (attention over each key set) shared between the calling
//   thread and the pool's threads (ModelOptions::step_threads). The caller works too and never waits for another
//   session's work: helpers that have not started when the caller ran out of tasks are taken back, so a call that
//   finds the threads busy runs all its tasks itself. Every task computes the same bits whichever thread runs it.
// - OrderedPool (engine/base/ordered_pool.h): numbered jobs whose results come back in job order.
// The threads run `thread_init` once before their first job (flush-to-zero for engine calls: engine_thread_init).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "absl/status/status.h"

namespace ss {

class ThreadPool {
 public:
  // `threads` threads (0 is allowed: parallel_for then runs on the caller alone; run() needs at least one).
  explicit ThreadPool(int threads, std::function<void()> thread_init = {});
  // Runs the jobs still queued, then joins the threads.
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int threads() const { return static_cast<int>(threads_.size()); }

  // Queues `job` to run on a pool thread (FIFO). A job that throws ends the program, as on any thread: run() is for
  // calls whose errors matter.
  void submit(std::function<void()> job);

  // Runs `fn` on a pool thread and returns its status; DEADLINE_EXCEEDED, without running it, when `deadline` passed
  // before a thread took it. A call that started runs to its end whatever the deadline. An exception (std::bad_alloc)
  // becomes INTERNAL, as gRPC's handlers report a throw to their caller.
  absl::Status run(std::chrono::steady_clock::time_point deadline, const std::function<absl::Status()>& fn);

  // Calls fn(task, thread) for every task in [0, tasks), on the calling thread and up to threads() pool threads;
  // `thread` in [0, threads()] names the scratch the task may use (0: the caller; no two tasks of one call run with
  // the same `thread` at once). Returns when every task is done. The pool threads' float modes (MXCSR: rounding,
  // flush-to-zero) are the caller's while they run the call's tasks, so the bits do not depend on who ran what.
  void parallel_for(int tasks, const std::function<void(int task, int thread)>& fn);

  // Jobs queued and not started.
  int waiting();

 private:
  struct Job {
    std::function<void()> owned;              // submit()'s job
    const std::function<void(int)>* borrowed = nullptr;  // run()'s and parallel_for()'s: called with the thread index
    bool done = false;
    std::condition_variable* done_cv = nullptr;  // notified (under mu_) when a borrowed job is done
  };
  void work(int index, const std::function<void()>& thread_init);
  // Takes `job` out of the queue if no thread started it; true if it did. Holds mu_.
  bool take_back_locked(Job* job);

  std::mutex mu_;
  std::condition_variable ready_;  // pool threads wait here for a job
  std::deque<Job*> queue_;         // in arrival order; owned jobs are deleted by the thread that ran them
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ss
