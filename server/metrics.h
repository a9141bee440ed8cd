// Prometheus text-format metrics, served by a tiny HTTP/1.0 responder on its own (loopback) port: the server's
// gRPC port stays gRPC-only.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

namespace ss::server {

class Metrics {
 public:
  void count_step(double seconds);
  void count_rejected(const std::string& code);
  void count_eviction() { evictions_++; }
  void count_call(const std::string& method) {
    std::lock_guard<std::mutex> l(mu_);
    calls_[method]++;
  }
  // Gauges read at scrape time.
  std::function<int()> sessions;
  std::function<uint64_t()> cache_bytes;

  std::string render() const;

 private:
  static constexpr std::array<double, 12> kBuckets = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
                                                       0.1,   0.25,   0.5,   1,    2.5,   10};
  mutable std::mutex mu_;
  std::array<uint64_t, kBuckets.size()> bucket_counts_{};
  uint64_t steps_ = 0;
  double step_seconds_sum_ = 0;
  std::map<std::string, uint64_t> rejected_, calls_;
  std::atomic<uint64_t> evictions_{0};
};

// Serves GET /metrics (any path, in fact) on host:port until stop(). Port 0 picks a free one (port() tells).
class MetricsHttp {
 public:
  MetricsHttp(const Metrics& m) : metrics_(m) {}
  ~MetricsHttp() { stop(); }
  bool start(const std::string& host, int port);
  int port() const { return port_; }
  void stop();

 private:
  void loop();
  const Metrics& metrics_;
  int fd_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace ss::server
