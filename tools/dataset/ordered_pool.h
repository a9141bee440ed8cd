// Runs numbered jobs 0, 1, 2, ... on worker threads and hands their results back in job order, so the output does
// not depend on how many workers there are or which finishes first. Workers run at most `lookahead` jobs past the
// one the consumer waits for, which bounds memory and the work thrown away when the consumer stops.
#pragma once

#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"

namespace ss::dataset {

template <class Result>
class OrderedPool {
 public:
  using Run = std::function<absl::StatusOr<Result>(int index)>;

  OrderedPool(int workers, int lookahead, Run run) : lookahead_(lookahead), run_(std::move(run)) {
    for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { work(); });
  }
  ~OrderedPool() {
    stop();
    for (std::thread& t : threads_) t.join();
  }
  OrderedPool(const OrderedPool&) = delete;
  OrderedPool& operator=(const OrderedPool&) = delete;

  // The result of the next job in order (blocks until it is done).
  absl::StatusOr<Result> next() {
    std::unique_lock lock(mu_);
    done_cv_.wait(lock, [&] { return done_.count(consumed_) > 0; });
    auto node = done_.extract(consumed_++);
    start_cv_.notify_all();
    return std::move(node.mapped());
  }

  // No job starts after this; running ones finish (and are discarded).
  void stop() {
    std::lock_guard lock(mu_);
    stopped_ = true;
    start_cv_.notify_all();
  }

 private:
  void work() {
    while (true) {
      int index;
      {
        std::unique_lock lock(mu_);
        start_cv_.wait(lock, [&] { return stopped_ || started_ < consumed_ + lookahead_; });
        if (stopped_) return;
        index = started_++;
      }
      absl::StatusOr<Result> r = run_(index);
      {
        std::lock_guard lock(mu_);
        done_.emplace(index, std::move(r));
      }
      done_cv_.notify_all();
    }
  }

  const int lookahead_;
  Run run_;
  std::mutex mu_;
  std::condition_variable start_cv_, done_cv_;
  std::map<int, absl::StatusOr<Result>> done_;
  int started_ = 0, consumed_ = 0;
  bool stopped_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace ss::dataset
