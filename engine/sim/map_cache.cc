#include "engine/sim/map_cache.h"

#include <cstring>

#include "engine/base/rng.h"
#include "engine/map/focus.h"

namespace ss {
namespace {

struct Fnv {
  uint64_t h = kFnv1aOffset;
  void bytes(const void* p, size_t n) { h = fnv1a64_bytes(p, n, h); }
  template <typename T>
  void pod(const T& v) { bytes(&v, sizeof v); }
};

}  // namespace

uint64_t map_content_hash(const Scenario& s) {
  Fnv f;
  for (const MapFeature& m : s.map_features) {
    f.pod(m.id);
    f.pod(m.kind);
    f.pod(m.subtype);
    for (const MapPoint& p : m.points) f.pod(p.x), f.pod(p.y), f.pod(p.z);
    for (int64_t lane : m.stop_sign_lanes) f.pod(lane);
  }
  const Vec2 focus = scenario_focus(s);
  f.pod(focus.x);
  f.pod(focus.y);
  return f.h;
}

absl::StatusOr<std::shared_ptr<const MapContext>> MapCache::get(const Scenario& s) {
  const uint64_t key = map_content_hash(s);
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto it = maps_.find(key); it != maps_.end())
      if (auto map = it->second.lock()) return map;
  }
  // Encoded outside the lock: two sessions racing on a new map may both encode it once; the first stored wins.
  auto map = model_->encode_map(nearest_segments(segment_map(s), scenario_focus(s), model_->config().max_map_segments));
  if (!map.ok()) return map.status();
  std::lock_guard<std::mutex> lock(mu_);
  ++encodes_;
  std::erase_if(maps_, [&](const auto& e) { return e.first != key && e.second.expired(); });
  auto& slot = maps_[key];
  if (auto existing = slot.lock()) return existing;
  slot = *map;
  return *map;
}

size_t MapCache::entries() const {
  std::lock_guard<std::mutex> lock(mu_);
  return maps_.size();
}

int MapCache::encodes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return encodes_;
}

}  // namespace ss
