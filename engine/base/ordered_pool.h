// Runs numbered jobs 0, 1, 2, ... on a ThreadPool (engine/base/thread_pool.h) and hands their results back in job
// order, so the output does not depend on how many workers there are or which finishes first. At most `lookahead`
// jobs past the one the consumer waits for are queued or running, which bounds memory and the work thrown away when
// the consumer stops. Jobs start in number order (the pool's queue is first in, first out).
#pragma once

#include <algorithm>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <optional>

#include "absl/status/statusor.h"
#include "engine/base/thread_pool.h"

namespace ss {

template <class Result>
class OrderedPool {
 public:
  using Run = std::function<absl::StatusOr<Result>(int index)>;

  // `workers` threads (at least one).
  OrderedPool(int workers, int lookahead, Run run)
      : lookahead_(std::max(1, lookahead)), run_(std::move(run)), pool_(std::max(1, workers)) {
    std::lock_guard lock(mu_);
    fill_locked();
  }
  // Stops; the pool (destroyed first) waits for the jobs that started, whose results are discarded.
  ~OrderedPool() { stop(); }
  OrderedPool(const OrderedPool&) = delete;
  OrderedPool& operator=(const OrderedPool&) = delete;

  // The result of the next job in order (blocks until it is done).
  absl::StatusOr<Result> next() {
    std::unique_lock lock(mu_);
    done_cv_.wait(lock, [&] { return done_.count(consumed_) > 0; });
    auto node = done_.extract(consumed_++);
    fill_locked();
    return std::move(node.mapped());
  }

  // No job starts after this; running ones finish (and are discarded).
  void stop() {
    std::lock_guard lock(mu_);
    stopped_ = true;
  }

 private:
  // Queues jobs up to `lookahead` past the consumer. Holds mu_.
  void fill_locked() {
    for (; !stopped_ && queued_ < consumed_ + lookahead_; ++queued_)
      pool_.submit([this, index = queued_] { work(index); });
  }
  void work(int index) {
    bool skip;
    {
      std::lock_guard lock(mu_);
      skip = stopped_;
    }
    std::optional<absl::StatusOr<Result>> r;
    if (!skip) r.emplace(run_(index));
    if (!r) return;
    std::lock_guard lock(mu_);
    done_.emplace(index, std::move(*r));
    done_cv_.notify_all();
  }

  const int lookahead_;
  Run run_;
  std::mutex mu_;
  std::condition_variable done_cv_;
  std::map<int, absl::StatusOr<Result>> done_;
  int queued_ = 0, consumed_ = 0;
  bool stopped_ = false;
  ThreadPool pool_;  // last: destroyed (its threads joined) first
};

}  // namespace ss
