// The server's Prometheus metrics, kept in a prometheus-cpp registry and served by its pull exposer (civetweb, on its
// own loopback port: the gRPC port stays gRPC-only).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "prometheus/counter.h"
#include "prometheus/exposer.h"
#include "prometheus/family.h"
#include "prometheus/histogram.h"
#include "prometheus/registry.h"

namespace ss::server {

class Metrics {
 public:
  Metrics();
  ~Metrics();
  void count_step(double seconds);
  void count_rejected(const std::string& code);
  void count_eviction();
  void count_call(const std::string& method);
  void count_malloc_trim();
  // Gauges read at scrape time.
  std::function<int()> sessions;
  std::function<uint64_t()> cache_bytes;
  std::function<int()> watchers;
  std::function<int()> compute_queued;

  // Serves GET /metrics on host:port (0: a free port) until the Metrics is destroyed; returns the port.
  absl::StatusOr<int> serve(const std::string& host, int port);
  // The text exposition format, as a scrape gets it.
  std::string render() const;

 private:
  class Gauges;
  std::shared_ptr<prometheus::Registry> registry_;
  std::shared_ptr<Gauges> gauges_;
  prometheus::Family<prometheus::Counter>& steps_;
  prometheus::Family<prometheus::Histogram>& step_seconds_;
  prometheus::Family<prometheus::Counter>& rejected_;
  prometheus::Family<prometheus::Counter>& calls_;
  prometheus::Family<prometheus::Counter>& evictions_;
  prometheus::Family<prometheus::Counter>& trims_;
  std::unique_ptr<prometheus::Exposer> exposer_;
};

}  // namespace ss::server
