#include "server/compute_queue.h"

#include <algorithm>
#include <exception>
#include <string>

namespace ss::server {

ComputeQueue::ComputeQueue(int threads, std::function<void()> thread_init) {
  for (int i = 0; i < std::max(1, threads); ++i) threads_.emplace_back([this, thread_init] { work(thread_init); });
}

ComputeQueue::~ComputeQueue() {
  {
    std::lock_guard<std::mutex> l(mu_);
    stop_ = true;
  }
  ready_.notify_all();
  for (std::thread& t : threads_) t.join();
}

absl::Status ComputeQueue::run(std::chrono::steady_clock::time_point deadline,
                               const std::function<absl::Status()>& fn) {
  Call call;
  call.fn = &fn;
  std::unique_lock<std::mutex> l(mu_);
  queue_.push_back(&call);
  ready_.notify_one();
  if (call.cv.wait_until(l, deadline, [&] { return call.done; })) return call.status;
  // The deadline passed: a call still queued is taken out; one that started is waited for (it reads our stack).
  if (auto it = std::find(queue_.begin(), queue_.end(), &call); it != queue_.end()) {
    queue_.erase(it);
    return absl::DeadlineExceededError("the call's deadline passed while waiting for a compute thread");
  }
  call.cv.wait(l, [&] { return call.done; });
  return call.status;
}

int ComputeQueue::waiting() {
  std::lock_guard<std::mutex> l(mu_);
  return static_cast<int>(queue_.size());
}

void ComputeQueue::work(const std::function<void()>& thread_init) {
  if (thread_init) thread_init();
  std::unique_lock<std::mutex> l(mu_);
  for (;;) {
    ready_.wait(l, [&] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, and nothing left to run
    Call* call = queue_.front();
    queue_.pop_front();
    l.unlock();
    absl::Status st;
    try {
      st = (*call->fn)();
    } catch (const std::exception& e) {  // as gRPC's handlers report a throw (std::bad_alloc) to their caller
      st = absl::InternalError(std::string("engine call failed: ") + e.what());
    }
    l.lock();
    call->status = std::move(st);
    call->done = true;
    call->cv.notify_one();  // under the lock: once it is released, the asking thread may return and free `call`
  }
}

}  // namespace ss::server
