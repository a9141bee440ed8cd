#include "engine/model/worker_pool.h"

#include <xmmintrin.h>

#include <algorithm>

namespace ss {

WorkerPool::WorkerPool(int threads) {
  for (int t = 1; t < std::max(threads, 1); ++t) workers_.emplace_back([this, t] { work(t); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> l(m_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void WorkerPool::run_tasks(int thread) {
  for (int i = next_.fetch_add(1); i < tasks_; i = next_.fetch_add(1)) (*fn_)(i, thread);
}

void WorkerPool::parallel_for(int tasks, const std::function<void(int, int)>& fn) {
  std::unique_lock<std::mutex> busy(busy_, std::try_to_lock);
  if (!busy.owns_lock() || workers_.empty() || tasks < 2) {
    for (int i = 0; i < tasks; ++i) fn(i, 0);
    return;
  }
  {
    std::lock_guard<std::mutex> l(m_);
    fn_ = &fn;
    csr_ = _mm_getcsr();
    tasks_ = tasks;
    next_ = 0;
    active_ = static_cast<int>(workers_.size());
    ++generation_;
  }
  wake_.notify_all();
  run_tasks(0);
  std::unique_lock<std::mutex> l(m_);
  done_.wait(l, [this] { return active_ == 0; });
  fn_ = nullptr;
}

void WorkerPool::work(int thread) {
  uint64_t seen = 0;
  std::unique_lock<std::mutex> l(m_);
  while (true) {
    wake_.wait(l, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    _mm_setcsr(csr_);  // the caller's float modes (flush-to-zero): the same bits on every thread
    l.unlock();
    run_tasks(thread);
    l.lock();
    if (--active_ == 0) done_.notify_one();
  }
}

}  // namespace ss
