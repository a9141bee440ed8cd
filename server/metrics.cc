#include "server/metrics.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>

namespace ss::server {

void Metrics::count_step(double seconds) {
  std::lock_guard<std::mutex> l(mu_);
  steps_++;
  step_seconds_sum_ += seconds;
  for (size_t i = 0; i < kBuckets.size(); ++i)
    if (seconds <= kBuckets[i]) bucket_counts_[i]++;
}

void Metrics::count_rejected(const std::string& code) {
  std::lock_guard<std::mutex> l(mu_);
  rejected_[code]++;
}

std::string Metrics::render() const {
  std::string o;
  char buf[256];
  o += "# HELP scenestreamer_sessions Sessions held in memory.\n# TYPE scenestreamer_sessions gauge\n";
  o += "scenestreamer_sessions " + std::to_string(sessions ? sessions() : 0) + "\n";
  o += "# HELP scenestreamer_cache_bytes Bytes held by sessions (KV caches and state).\n"
       "# TYPE scenestreamer_cache_bytes gauge\n";
  o += "scenestreamer_cache_bytes " + std::to_string(cache_bytes ? cache_bytes() : 0) + "\n";
  o += "# HELP scenestreamer_evictions_total Idle sessions evicted to make room.\n"
       "# TYPE scenestreamer_evictions_total counter\n";
  o += "scenestreamer_evictions_total " + std::to_string(evictions_.load()) + "\n";
  std::lock_guard<std::mutex> l(mu_);
  o += "# HELP scenestreamer_steps_total Ticks computed.\n# TYPE scenestreamer_steps_total counter\n";
  o += "scenestreamer_steps_total " + std::to_string(steps_) + "\n";
  o += "# HELP scenestreamer_step_seconds Time to compute one tick.\n# TYPE scenestreamer_step_seconds histogram\n";
  for (size_t i = 0; i < kBuckets.size(); ++i) {
    std::snprintf(buf, sizeof buf, "scenestreamer_step_seconds_bucket{le=\"%g\"} %llu\n", kBuckets[i],
                  static_cast<unsigned long long>(bucket_counts_[i]));
    o += buf;
  }
  o += "scenestreamer_step_seconds_bucket{le=\"+Inf\"} " + std::to_string(steps_) + "\n";
  std::snprintf(buf, sizeof buf, "scenestreamer_step_seconds_sum %.6f\n", step_seconds_sum_);
  o += buf;
  o += "scenestreamer_step_seconds_count " + std::to_string(steps_) + "\n";
  o += "# HELP scenestreamer_rejected_total Calls refused, by gRPC status code.\n"
       "# TYPE scenestreamer_rejected_total counter\n";
  for (const auto& [code, n] : rejected_)
    o += "scenestreamer_rejected_total{code=\"" + code + "\"} " + std::to_string(n) + "\n";
  o += "# HELP scenestreamer_calls_total Calls received, by method.\n# TYPE scenestreamer_calls_total counter\n";
  for (const auto& [m, n] : calls_) o += "scenestreamer_calls_total{method=\"" + m + "\"} " + std::to_string(n) + "\n";
  return o;
}

bool MetricsHttp::start(const std::string& host, int port) {
  fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd_ < 0) return false;
  int one = 1;
  ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  if (::inet_pton(AF_INET, host.c_str(), &a.sin_addr) != 1) return false;
  if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 16) != 0) {
    ::close(fd_);
    fd_ = -1;
    return false;
  }
  socklen_t len = sizeof a;
  ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
  port_ = ntohs(a.sin_port);
  thread_ = std::thread([this] { loop(); });
  return true;
}

void MetricsHttp::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void MetricsHttp::loop() {
  while (!stop_) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, 200) <= 0) continue;
    const int c = ::accept(fd_, nullptr, nullptr);
    if (c < 0) continue;
    // One short request per connection (HTTP/1.0): read what arrives within a moment, answer, close.
    char req[2048];
    pollfd q{c, POLLIN, 0};
    if (::poll(&q, 1, 1000) > 0) (void)::recv(c, req, sizeof req, 0);
    const std::string body = metrics_.render();
    const std::string resp = "HTTP/1.0 200 OK\r\nContent-Type: text/plain; version=0.0.4\r\nContent-Length: " +
                             std::to_string(body.size()) + "\r\n\r\n" + body;
    size_t sent = 0;
    while (sent < resp.size()) {
      const ssize_t n = ::send(c, resp.data() + sent, resp.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += static_cast<size_t>(n);
    }
    ::close(c);
  }
}

}  // namespace ss::server
