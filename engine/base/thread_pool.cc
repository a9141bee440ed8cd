#include "engine/base/thread_pool.h"

#include <xmmintrin.h>

#include <algorithm>
#include <exception>
#include <string>

namespace ss {

ThreadPool::ThreadPool(int threads, std::function<void()> thread_init) {
  for (int i = 0; i < std::max(0, threads); ++i)
    threads_.emplace_back([this, i, thread_init] { work(i, thread_init); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> l(mu_);
    stop_ = true;
  }
  ready_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void ThreadPool::submit(std::function<void()> job) {
  auto* j = new Job;
  j->owned = std::move(job);
  {
    std::lock_guard<std::mutex> l(mu_);
    queue_.push_back(j);
  }
  ready_.notify_one();
}

bool ThreadPool::take_back_locked(Job* job) {
  auto it = std::find(queue_.begin(), queue_.end(), job);
  if (it == queue_.end()) return false;
  queue_.erase(it);
  return true;
}

absl::Status ThreadPool::run(std::chrono::steady_clock::time_point deadline, const std::function<absl::Status()>& fn) {
  absl::Status status;
  const std::function<void(int)> body = [&](int) {
    try {
      status = fn();
    } catch (const std::exception& e) {
      status = absl::InternalError(std::string("engine call failed: ") + e.what());
    }
  };
  if (threads_.empty()) {  // nobody to hand it to
    body(0);
    return status;
  }
  std::condition_variable done;
  Job job;
  job.borrowed = &body;
  job.done_cv = &done;
  std::unique_lock<std::mutex> l(mu_);
  queue_.push_back(&job);
  ready_.notify_one();
  if (done.wait_until(l, deadline, [&] { return job.done; })) return status;
  // The deadline passed: a call still queued is taken out; one that started is waited for (it reads our stack).
  if (take_back_locked(&job))
    return absl::DeadlineExceededError("the call's deadline passed while waiting for a compute thread");
  done.wait(l, [&] { return job.done; });
  return status;
}

void ThreadPool::parallel_for(int tasks, const std::function<void(int, int)>& fn) {
  const int helpers = std::min(threads(), tasks - 1);
  if (helpers <= 0) {
    for (int i = 0; i < tasks; ++i) fn(i, 0);
    return;
  }
  std::atomic<int> next{0};
  const unsigned csr = _mm_getcsr();
  const std::function<void(int)> help = [&](int thread) {
    const unsigned own = _mm_getcsr();
    _mm_setcsr(csr);  // the caller's float modes (flush-to-zero): the same bits on every thread
    for (int i = next.fetch_add(1); i < tasks; i = next.fetch_add(1)) fn(i, thread);
    _mm_setcsr(own);
  };
  std::condition_variable done;
  std::vector<Job> jobs(helpers);
  {
    std::lock_guard<std::mutex> l(mu_);
    for (Job& j : jobs) {
      j.borrowed = &help;
      j.done_cv = &done;
      queue_.push_back(&j);
    }
  }
  if (helpers == 1)
    ready_.notify_one();
  else
    ready_.notify_all();
  for (int i = next.fetch_add(1); i < tasks; i = next.fetch_add(1)) fn(i, 0);
  // Out of tasks: helpers still queued (the threads were busy) are taken back, started ones finish their last task.
  std::unique_lock<std::mutex> l(mu_);
  for (Job& j : jobs)
    if (!take_back_locked(&j)) done.wait(l, [&] { return j.done; });
}

int ThreadPool::waiting() {
  std::lock_guard<std::mutex> l(mu_);
  return static_cast<int>(queue_.size());
}

void ThreadPool::work(int index, const std::function<void()>& thread_init) {
  if (thread_init) thread_init();
  std::unique_lock<std::mutex> l(mu_);
  for (;;) {
    ready_.wait(l, [&] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, and nothing left to run
    Job* job = queue_.front();
    queue_.pop_front();
    l.unlock();
    if (job->borrowed == nullptr) {
      job->owned();
      delete job;
      l.lock();
      continue;
    }
    (*job->borrowed)(index + 1);
    l.lock();
    job->done = true;
    // Under the lock: once it is released, the waiting thread may return and free `job`.
    job->done_cv->notify_all();
  }
}

}  // namespace ss
