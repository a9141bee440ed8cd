#include "engine/model/kv_cache.h"

#include <algorithm>

namespace ss {

void KvCache::init(int layers, int d) {
  tokens.clear();
  anchors.clear();
  k.assign(layers, {});
  v.assign(layers, {});
  head = 0;
  capacity = 0;
  d_model = d;
  next_seq = 0;
  cross_keys.clear();
}

void KvCache::reserve(int n) {
  if (n <= capacity) return;
  const int grown = std::max(n, 2 * size());  // as a vector grows: twice what is held, not twice the ring
  const size_t d = d_model;
  auto relay = [&](std::vector<float>& ring) {
    std::vector<float> fresh(static_cast<size_t>(grown) * d);
    for (int j = 0; j < size(); ++j)
      std::copy_n(ring.data() + static_cast<size_t>(row(j)) * d, d, fresh.data() + static_cast<size_t>(j) * d);
    ring = std::move(fresh);
  };
  for (size_t l = 0; l < k.size(); ++l) {
    relay(k[l]);
    relay(v[l]);
  }
  head = 0;
  capacity = grown;
}

void KvCache::evict_before(int first_step) {
  // Tokens are appended step by step, so the old ones form a prefix.
  const auto first_kept = std::find_if(tokens.begin(), tokens.end(),
                                       [&](const DecoderToken& t) { return t.step >= first_step; });
  const int drop = static_cast<int>(first_kept - tokens.begin());
  if (drop == 0) return;
  head = drop == size() ? 0 : row(drop);
  tokens.erase(tokens.begin(), first_kept);
  anchors.erase(anchors.begin(), anchors.begin() + drop);
}

void KvCache::truncate(int n) {
  if (n >= size()) return;
  next_seq -= size() - n;
  tokens.resize(n);
  anchors.resize(n);
}

size_t KvCache::bytes() const {
  size_t b = tokens.capacity() * sizeof(DecoderToken) + anchors.capacity() * sizeof(Anchor);
  for (size_t l = 0; l < k.size(); ++l) b += (k[l].capacity() + v[l].capacity()) * sizeof(float);
  for (const auto& [pose, e] : cross_keys) {
    const QueryKeys& q = *e.keys;
    // The map node (its key, value and four links), the set and its arrays.
    b += sizeof(pose) + sizeof(e) + 4 * sizeof(void*) + sizeof(q) + q.keys.capacity() * sizeof(int) +
         q.table_runs.capacity() * sizeof(QueryKeys::TableRun) + q.relation.size() * sizeof(float);
  }
  return b;
}

}  // namespace ss
