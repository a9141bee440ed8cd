#include "server/metrics.h"

#include <exception>

#include "absl/strings/str_cat.h"
#include "server/allocator.h"
#include "prometheus/collectable.h"
#include "prometheus/gauge.h"
#include "prometheus/metric_family.h"
#include "prometheus/text_serializer.h"

namespace ss::server {
namespace {

// Seconds per tick: from a small model's sub-tick (1 ms) to a large one's step under load.
const prometheus::Histogram::BucketBoundaries kStepBuckets = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
                                                              0.1,   0.25,   0.5,   1,    2.5,   10};

prometheus::Family<prometheus::Counter>& counter(prometheus::Registry& r, const char* name, const char* help) {
  return prometheus::BuildCounter().Name(name).Help(help).Register(r);
}

}  // namespace

// The gauges whose values live elsewhere (the session manager), read when a scrape asks.
class Metrics::Gauges : public prometheus::Collectable {
 public:
  explicit Gauges(const Metrics& m) : m_(m) {}
  std::vector<prometheus::MetricFamily> Collect() const override {
    auto family = [](const char* name, const char* help, double v) {
      prometheus::MetricFamily f;
      f.name = name;
      f.help = help;
      f.type = prometheus::MetricType::Gauge;
      f.metric.emplace_back().gauge.value = v;
      return f;
    };
    const AllocatorStats a = allocator_stats();
    return {family("scenestreamer_sessions", "Sessions held in memory.", m_.sessions ? m_.sessions() : 0),
            family("scenestreamer_cache_bytes", "Bytes held by sessions (KV caches and state).",
                   m_.cache_bytes ? static_cast<double>(m_.cache_bytes()) : 0),
            family("scenestreamer_watchers", "WatchSession streams open.", m_.watchers ? m_.watchers() : 0),
            // Above zero for long: the compute threads are the bottleneck (more replicas, or a smaller model).
            family("scenestreamer_compute_queued", "Engine calls (ticks, creates, forks) waiting for a compute thread.",
                   m_.compute_queued ? m_.compute_queued() : 0),
            // What RSS is made of (server/allocator.h): bytes in use vs bytes the allocator holds beyond them.
            family("scenestreamer_malloc_in_use_bytes",
                   "Bytes allocated with malloc and not freed (jemalloc stats.allocated).", static_cast<double>(a.in_use)),
            family("scenestreamer_malloc_free_bytes",
                   "Bytes resident in the allocator beyond those in use: unused pages not yet given back, metadata "
                   "(jemalloc stats.resident - stats.allocated).",
                   static_cast<double>(a.free)),
            family("scenestreamer_resident_bytes", "The server's resident memory (RSS).",
                   static_cast<double>(a.resident))};
  }

 private:
  const Metrics& m_;
};

Metrics::Metrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      gauges_(std::make_shared<Gauges>(*this)),
      steps_(counter(*registry_, "scenestreamer_steps_total", "Ticks computed.")),
      step_seconds_(prometheus::BuildHistogram()
                        .Name("scenestreamer_step_seconds")
                        .Help("Time to compute one tick.")
                        .Register(*registry_)),
      rejected_(counter(*registry_, "scenestreamer_rejected_total", "Calls refused, by gRPC status code.")),
      calls_(counter(*registry_, "scenestreamer_calls_total", "Calls received, by method.")),
      evictions_(counter(*registry_, "scenestreamer_evictions_total", "Idle sessions evicted to make room.")),
      trims_(counter(*registry_, "scenestreamer_malloc_trims_total",
                     "Allocator purges (unused pages given back) after sessions closed (--malloc_trim_s).")) {
  // Series without labels exist from the start, so a scrape shows them at zero.
  steps_.Add({});
  step_seconds_.Add({}, kStepBuckets);
  evictions_.Add({});
  trims_.Add({});
}

Metrics::~Metrics() = default;

void Metrics::count_step(double seconds) {
  steps_.Add({}).Increment();
  step_seconds_.Add({}, kStepBuckets).Observe(seconds);
}

void Metrics::count_rejected(const std::string& code) { rejected_.Add({{"code", code}}).Increment(); }
void Metrics::count_eviction() { evictions_.Add({}).Increment(); }
void Metrics::count_malloc_trim() { trims_.Add({}).Increment(); }
void Metrics::count_call(const std::string& method) { calls_.Add({{"method", method}}).Increment(); }

absl::StatusOr<int> Metrics::serve(const std::string& host, int port) {
  // Enough worker threads that idle connections do not hold up a scrape, and a short request timeout that frees
  // the workers such connections take (civetweb serves one connection per worker).
  try {
    exposer_ = std::make_unique<prometheus::Exposer>(std::vector<std::string>{
        "listening_ports", absl::StrCat(host, ":", port), "num_threads", "16", "request_timeout_ms", "2000"});
  } catch (const std::exception& e) {
    return absl::UnavailableError(absl::StrCat("metrics on ", host, ":", port, ": ", e.what()));
  }
  exposer_->RegisterCollectable(registry_);
  exposer_->RegisterCollectable(gauges_);
  const std::vector<int> ports = exposer_->GetListeningPorts();
  if (ports.empty()) return absl::UnavailableError(absl::StrCat("metrics on ", host, ":", port, ": no port bound"));
  return ports[0];
}

std::string Metrics::render() const {
  std::vector<prometheus::MetricFamily> all = registry_->Collect();
  for (auto& f : gauges_->Collect()) all.push_back(std::move(f));
  return prometheus::TextSerializer().Serialize(all);
}

}  // namespace ss::server
