#include "engine/model/kv_cache.h"

#include <algorithm>

namespace ss {

void KvCache::init(int layers, int d) {
  tokens.clear();
  anchors.clear();
  k.assign(layers, {});
  v.assign(layers, {});
  d_model = d;
  next_seq = 0;
  cross_keys.clear();
}

void KvCache::evict_before(int first_step) {
  // Tokens are appended step by step, so the old ones form a prefix.
  const auto first_kept = std::find_if(tokens.begin(), tokens.end(),
                                       [&](const DecoderToken& t) { return t.step >= first_step; });
  const size_t drop = first_kept - tokens.begin();
  if (drop == 0) return;
  tokens.erase(tokens.begin(), first_kept);
  anchors.erase(anchors.begin(), anchors.begin() + drop);
  for (size_t l = 0; l < k.size(); ++l) {
    k[l].erase(k[l].begin(), k[l].begin() + drop * d_model);
    v[l].erase(v[l].begin(), v[l].begin() + drop * d_model);
  }
}

void KvCache::truncate(int n) {
  if (n >= size()) return;
  next_seq -= size() - n;
  tokens.resize(n);
  anchors.resize(n);
  for (size_t l = 0; l < k.size(); ++l) {
    k[l].resize(static_cast<size_t>(n) * d_model);
    v[l].resize(static_cast<size_t>(n) * d_model);
  }
}

size_t KvCache::bytes() const {
  size_t b = tokens.capacity() * sizeof(DecoderToken) + anchors.capacity() * sizeof(Anchor);
  for (size_t l = 0; l < k.size(); ++l) b += (k[l].capacity() + v[l].capacity()) * sizeof(float);
  for (const auto& [pose, e] : cross_keys) {
    const QueryKeys& q = *e.keys;
    b += sizeof(pose) + sizeof(e) + sizeof(q) + 4 * sizeof(void*) + q.keys.capacity() * sizeof(int) +
         q.table_runs.capacity() * sizeof(QueryKeys::TableRun) + q.relation.size() * sizeof(float);
  }
  return b;
}

}  // namespace ss
