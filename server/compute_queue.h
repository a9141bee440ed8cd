// Engine calls run on a fixed set of compute threads, as TF Serving's batch scheduler and llama.cpp's server loop
// run theirs. The gRPC thread that asks waits for the call's result. In arrival order: an unordered semaphore once let
// some sessions wait >10 s under 32 clients while others went straight through (p99 11.4 s against p50 35 ms).
//
// Before, each of up to 32 gRPC threads ran its own calls once it held one of `threads` slots. Measured under 32
// clients on 2 cores: the cores sat idle 7 % of the time, as each hand-over woke another thread that the scheduler
// often queued behind a busy core for a few ms while the other core idled, and each call ran on a thread whose
// scratch (the attention's, the bf16 products') had gone cold. A compute thread now takes the next call as soon as
// it finishes one, without sleeping, and keeps its scratch warm.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "absl/status/status.h"

namespace ss::server {

class ComputeQueue {
 public:
  // `threads` compute threads (at least one), each running `thread_init` once before its first call.
  ComputeQueue(int threads, std::function<void()> thread_init);
  // Runs the calls still queued, then joins the threads.
  ~ComputeQueue();
  ComputeQueue(const ComputeQueue&) = delete;
  ComputeQueue& operator=(const ComputeQueue&) = delete;

  // Runs `fn` on a compute thread and returns its status; DEADLINE_EXCEEDED, without running it, when `deadline`
  // passed before a thread took it. A call that started runs to its end whatever the deadline.
  absl::Status run(std::chrono::steady_clock::time_point deadline, const std::function<absl::Status()>& fn);

  // Calls queued and not started.
  int waiting();

 private:
  struct Call {
    const std::function<absl::Status()>* fn = nullptr;
    absl::Status status;
    bool done = false;
    std::condition_variable cv;  // the asking thread waits here for `done`
  };
  void work(const std::function<void()>& thread_init);

  std::mutex mu_;
  std::condition_variable ready_;  // compute threads wait here for a call
  std::deque<Call*> queue_;        // in arrival order
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ss::server
