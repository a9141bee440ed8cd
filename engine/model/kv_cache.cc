#include "engine/model/kv_cache.h"

#include <algorithm>
#include <type_traits>

#include "engine/model/attention_kernels.h"

namespace ss {

void KvCache::init(int layers, int d, KvPrecision p) {
  tokens.clear();
  anchors.clear();
  precision = p;
  k.assign(half() ? 0 : layers, {});
  v.assign(half() ? 0 : layers, {});
  kh.assign(half() ? layers : 0, {});
  vh.assign(half() ? layers : 0, {});
  head = 0;
  capacity = 0;
  d_model = d;
  next_seq = 0;
  cross_keys.clear();
  poseless.clear();
}

void KvCache::reserve(int n) {
  if (n <= capacity) return;
  // An eighth more than asked: a session's cache size settles once its window is full (the tokens of W steps), so
  // the ring stops growing after a few steps; doubling it would hold up to twice the window for good.
  const int grown = std::max(n + n / 8, 16);
  const size_t d = d_model;
  auto relay = [&](auto& ring) {
    std::remove_reference_t<decltype(ring)> fresh(static_cast<size_t>(grown) * d);
    for (int j = 0; j < size(); ++j)
      std::copy_n(ring.data() + static_cast<size_t>(row(j)) * d, d, fresh.data() + static_cast<size_t>(j) * d);
    ring = std::move(fresh);
  };
  for (size_t l = 0; l < k.size(); ++l) {
    relay(k[l]);
    relay(v[l]);
  }
  for (size_t l = 0; l < kh.size(); ++l) {
    relay(kh[l]);
    relay(vh[l]);
  }
  head = 0;
  capacity = grown;
}

void KvCache::read_key(int layer, int j, float* out) const {
  const size_t at = static_cast<size_t>(row(j)) * d_model;
  if (half()) halves_to_floats(kh[layer].data() + at, d_model, out);
  else std::copy_n(k[layer].data() + at, d_model, out);
}

void KvCache::read_value(int layer, int j, float* out) const {
  const size_t at = static_cast<size_t>(row(j)) * d_model;
  if (half()) halves_to_floats(vh[layer].data() + at, d_model, out);
  else std::copy_n(v[layer].data() + at, d_model, out);
}

namespace {

template <typename T>
void write_rows(const KvCache& c, std::vector<T>& ring, int first, const float* src, int n) {
  for (int i = 0; i < n; ++i) {
    const size_t at = static_cast<size_t>(c.row(first + i)) * c.d_model;
    const float* from = src + static_cast<size_t>(i) * c.d_model;
    if constexpr (std::is_same_v<T, float>) std::copy_n(from, c.d_model, ring.data() + at);
    else floats_to_halves(from, c.d_model, ring.data() + at);
  }
}

}  // namespace

void KvCache::write_keys(int layer, int first, const float* src, int n) {
  if (half()) write_rows(*this, kh[layer], first, src, n);
  else write_rows(*this, k[layer], first, src, n);
}

void KvCache::write_values(int layer, int first, const float* src, int n) {
  if (half()) write_rows(*this, vh[layer], first, src, n);
  else write_rows(*this, v[layer], first, src, n);
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
  for (size_t l = 0; l < kh.size(); ++l) b += (kh[l].capacity() + vh[l].capacity()) * sizeof(uint16_t);
  // The kept position-less rows: map nodes and their vectors.
  for (const auto& [key, e] : poseless) b += sizeof(key) + sizeof(e) + 4 * sizeof(void*) + e.x.size() * sizeof(float);
  for (const auto& [pose, e] : cross_keys) {
    const QueryKeys& q = *e.keys;
    // The map node (its key, value and four links), the set and its arrays.
    b += sizeof(pose) + sizeof(e) + 4 * sizeof(void*) + sizeof(q) + q.keys.capacity() * sizeof(int) +
         q.table_runs.capacity() * sizeof(QueryKeys::TableRun) + q.relation.size() * sizeof(float);
  }
  return b;
}

}  // namespace ss
