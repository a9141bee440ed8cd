// The decoder: token embeddings, which keys each token reads, and the layer stack over the KV cache.
#include <algorithm>
#include <cstdlib>
#include <map>
#include <optional>

#include "engine/model/key_select.h"
#include "engine/model/model.h"

namespace ss {

KvCache Model::new_cache() const {
  KvCache cache;
  cache.init(config().decoder_layers, config().d_model, kv_precision());
  return cache;
}

Mat Model::embed(std::span<const DecoderToken> tokens) const {
  const int d = config().d_model;
  const int n = static_cast<int>(tokens.size());
  auto row = [d](const float* table, int i) { return VecMap(table + static_cast<size_t>(i) * d, d); };
  Mat x = Mat::Zero(n, d);
  // The two small MLPs run batched over the tokens that use them.
  std::vector<int> motion_rows, rs_rows;
  for (int i = 0; i < n; ++i) {
    const DecoderToken& t = tokens[i];
    auto xi = x.row(i);
    switch (t.kind) {
      case TokenKind::light:
        xi = row(light_state_emb_, t.light_state) + row(light_slot_emb_, t.light_slot) + row(map_id_embedding_, t.map_id);
        break;
      case TokenKind::sos: xi = row(special_emb_, kSpecialSos); break;
      case TokenKind::eos: xi = row(special_emb_, kSpecialEos); break;
      case TokenKind::soa:
        xi = row(special_emb_, kSpecialSoa) + row(intra_emb_, t.intra_index) + row(agent_slot_emb_, t.agent_slot);
        break;
      case TokenKind::type:
        xi = row(intra_emb_, t.intra_index) + row(agent_slot_emb_, t.agent_slot) + row(agent_type_emb_, t.agent_type);
        break;
      case TokenKind::map_segment:
      case TokenKind::relative_state:
        xi = row(intra_emb_, t.intra_index) + row(agent_slot_emb_, t.agent_slot) + row(agent_type_emb_, t.agent_type) +
             row(map_id_embedding_, t.map_id);
        if (t.kind == TokenKind::relative_state) rs_rows.push_back(i);
        break;
      case TokenKind::motion:
        xi = row(motion_action_emb_, t.motion_action) + row(agent_type_emb_, t.agent_type) +
             row(agent_slot_emb_, t.agent_slot);
        motion_rows.push_back(i);
        break;
    }
  }
  auto add_mlp = [&](const std::vector<int>& rows, int width, auto features, const LinearParams& fc1,
                     const LinearParams& fc2) {
    if (rows.empty()) return;
    Mat in(rows.size(), width);
    for (size_t r = 0; r < rows.size(); ++r) in.row(r) = Eigen::Map<const Vec>(features(tokens[rows[r]]), width);
    Mat h = linear(in, fc1);
    relu_inplace(h);
    h = linear(h, fc2);
    for (size_t r = 0; r < rows.size(); ++r) x.row(rows[r]) += h.row(r);
  };
  add_mlp(motion_rows, kMotionStateFeatures, [](const DecoderToken& t) { return t.motion_state.data(); },
          motion_state_fc1_, motion_state_fc2_);
  add_mlp(rs_rows, kRsFields, [](const DecoderToken& t) { return t.relative_state.data(); }, rs_embed_fc1_,
          rs_embed_fc2_);
  return x;
}

namespace {

Anchor anchor_of(const DecoderToken& t) { return Anchor(t.has_pose, t.pose, t.step); }

// The embedding inputs of a position-less token that its first layer's cross-attention depends on (Model::embed),
// or nothing for tokens that do not take the kept path.
std::optional<PoselessKey> poseless_key(const DecoderToken& t) {
  if (t.has_pose) return std::nullopt;
  const auto kind = static_cast<uint8_t>(t.kind);
  switch (t.kind) {
    case TokenKind::sos:
    case TokenKind::eos: return PoselessKey{kind, 0, 0, 0};
    case TokenKind::soa: return PoselessKey{kind, t.intra_index, t.agent_slot, 0};
    case TokenKind::type: return PoselessKey{kind, t.intra_index, t.agent_slot, t.agent_type};
    default: return std::nullopt;
  }
}

}  // namespace

Model::KeySets Model::self_keys(const KvCache& cache, std::span<const DecoderToken> tokens) const {
  const int c = cache.size();
  auto token = [&](int j) -> const DecoderToken& { return j < c ? cache.tokens[j] : tokens[j - c]; };
  std::vector<Anchor> fresh;  // the new tokens' anchors; the cached ones are in cache.anchors
  for (const DecoderToken& t : tokens) fresh.push_back(anchor_of(t));
  auto anchor = [&](int j) -> const Anchor& { return j < c ? cache.anchors[j] : fresh[j - c]; };

  const int n = static_cast<int>(tokens.size());
  KeySets out;
  out.sets.resize(n);
  out.per_query.resize(n);
  // One selector (and its scratch) per thread: each query's keys depend on the query alone.
  std::vector<SelfKeySelector> selectors(1, SelfKeySelector(cache.tokens, tokens, config().window_steps, limit_));
  if (pool_ && n > 1) selectors.resize(pool_->threads() + 1, selectors[0]);  // the caller's and the pool's
  std::vector<SelfKeys> keys(selectors.size());
  std::vector<QueryKeys*> sets(n);
  std::vector<std::vector<float>> features(n);  // per query: its posed keys' relation features, row by row
  auto select = [&](int i, int thread) {
    SelfKeys& k = keys[thread];
    selectors[thread].select(i, k);
    // Pairs with a position on both sides go through the relation MLP (below, set_relation_columns, for all the
    // queries); the others depend only on the step difference and share the rows of the table.
    auto set = std::make_shared<QueryKeys>();
    set->keys = k.posed;
    for (int j : k.unposed) set->add_table_row(tokens[i].step - token(j).step);
    std::vector<float>& f = features[i];
    f.resize(set->keys.size() * kRelationFeatures);
    for (size_t e = 0; e < set->keys.size(); ++e) {
      const RelationFeatures rf = relation_features(fresh[i], anchor(set->keys[e]));
      std::copy(rf.begin(), rf.end(), f.begin() + e * kRelationFeatures);
    }
    set->keys.insert(set->keys.end(), k.unposed.begin(), k.unposed.end());
    for (int& j : set->keys) j = cache.row(j);  // the attention reads keys and values at their ring rows
    set->table = &self_relation_by_step_;
    sets[i] = set.get();
    out.per_query[i] = set.get();
    out.sets[i] = std::move(set);
  };
  if (selectors.size() > 1) pool_->parallel_for(n, select);
  else
    for (int i = 0; i < n; ++i) select(i, 0);
  set_relation_columns(sets, features, self_relation_);
  return out;
}

Model::KeySets Model::cross_keys(const MapContext& map, KvCache& cache, std::span<const DecoderToken> tokens) const {
  KeySets out;
  std::vector<QueryKeys*> fresh_sets;        // the sets made by this call
  std::vector<std::vector<float>> features;  // their posed keys' relation features
  const int m = map.size();
  const QueryKeys* whole_map = nullptr;  // for queries without a position: every segment, no spatial relation
  for (const DecoderToken& q : tokens) {
    if (!q.has_pose) {
      if (!whole_map) {
        auto set = std::make_shared<QueryKeys>();
        set->keys.resize(m);
        for (int j = 0; j < m; ++j) set->keys[j] = j;
        set->table = &cross_relation_at_rest_;  // no position: every map key has the same relation
        set->table_runs = {{0, m}};
        set->uniform = true;
        whole_map = set.get();
        out.sets.push_back(std::move(set));
      }
      out.per_query.push_back(whole_map);
      continue;
    }
    CrossKeyEntry& entry = cache.cross_keys[{q.pose.x, q.pose.y, q.pose.heading}];
    entry.last_step = std::max(entry.last_step, q.step);
    if (!entry.keys) {
      auto set = std::make_shared<QueryKeys>();
      set->keys = map_keys_near(map.segments, map.index, {q.pose.x, q.pose.y}, limit_);
      // Map tokens are static: they carry the query's step, so the step difference is 0.
      const Anchor qa(true, q.pose, 0);
      std::vector<float>& f = features.emplace_back(set->keys.size() * kRelationFeatures);
      for (size_t j = 0; j < set->keys.size(); ++j) {
        const RelationFeatures rf = relation_features(qa, map.anchors[set->keys[j]]);
        std::copy(rf.begin(), rf.end(), f.begin() + j * kRelationFeatures);
      }
      fresh_sets.push_back(set.get());  // its relation columns: below, with the other new sets'
      entry.keys = set;
      out.sets.push_back(std::move(set));
    }
    out.per_query.push_back(entry.keys.get());
  }
  set_relation_columns(fresh_sets, features, cross_relation_);
  // Poses not read at the newest step (an agent that moved, a light gone) are not kept.
  const int newest = tokens.back().step;
  std::erase_if(cache.cross_keys, [&](const auto& e) { return e.second.last_step < newest; });
  return out;
}

Mat Model::decode(const MapContext& map, KvCache& cache, std::vector<DecoderToken>& tokens) const {
  std::vector<int> all(tokens.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return decode(map, cache, tokens, all);
}

Mat Model::decode(const MapContext& map, KvCache& cache, std::vector<DecoderToken>& tokens,
                  std::span<const int> outputs) const {
  const ModelConfig& c = config();
  const int n = static_cast<int>(tokens.size());
  if (n == 0) return Mat(0, c.d_model);
  for (int i = 0; i < n; ++i) tokens[i].seq = cache.next_seq + i;
  cache.reserve(cache.size() + n);  // before the keys are named by their ring rows
  const KeySets self = self_keys(cache, tokens);
  const KeySets cross = cross_keys(map, cache, tokens);
  std::vector<const QueryKeys*> self_out;  // the last layer's self-attention runs for the output rows only
  for (int i : outputs) self_out.push_back(self.per_query[i]);
  count_work(cache.work, self, cross, outputs);

  Mat x = embed(tokens);
  // Position-less tokens take their first layer's cross-attention from the cache's kept rows (computed here, one
  // token at a time, when missing); the other tokens run it as a batch.
  std::vector<int> computed;  // rows whose first cross-attention runs here
  const int newest = tokens.back().step;
  for (int i = 0; i < n; ++i) {
    const auto key = poseless_key(tokens[i]);
    if (!key) {
      computed.push_back(i);
      continue;
    }
    PoselessEntry& e = cache.poseless[*key];
    e.last_step = std::max(e.last_step, tokens[i].step);
    if (e.x.size() != 0) {  // kept: this layer's cross-attention is not run (nor counted)
      ++cache.work.kept_cross_queries;
      cache.work.key_reads -= static_cast<int64_t>(cross.per_query[i]->keys.size());
      cache.work.posed_key_reads -= cross.per_query[i]->posed();
    } else {
      const DecoderLayerParams& L = decoder_layers_[0];
      const Mat xi = x.row(i);
      const QueryKeys* one[] = {cross.per_query[i]};
      e.x = xi + relative_attention(layer_norm(xi, L.cross_norm), L.cross, c.heads,
                                    MatMap(map.cross_keys[0].data(), map.size(), c.d_model),
                                    MatMap(map.cross_values[0].data(), map.size(), c.d_model), one);
    }
    x.row(i) = e.x;
  }
  // A step's tokens may come in several calls (lights, then the agent-state group, ...): rows read at the step before
  // stay until the step after, so a call that reads none of them (lights) does not drop them.
  std::erase_if(cache.poseless, [&](const auto& e) { return e.second.last_step < newest - 1; });
  std::vector<const QueryKeys*> cross_computed;
  for (int i : computed) cross_computed.push_back(cross.per_query[i]);

  for (int l = 0; l < c.decoder_layers; ++l) {
    const DecoderLayerParams& L = decoder_layers_[l];
    // Floats (with halves beside them in fp16), or halves alone where the floats are not kept (MapContext).
    KeyValueRows map_keys = map.cross_keys[l].size() != 0
                                ? KeyValueRows(MatMap(map.cross_keys[l].data(), map.size(), c.d_model),
                                               MatMap(map.cross_values[l].data(), map.size(), c.d_model))
                                : KeyValueRows(map.cross_keys_h[l].data(), map.cross_values_h[l].data(), map.size(),
                                               c.d_model);
    if (!map.cross_keys_h.empty()) {
      map_keys.kh = map.cross_keys_h[l].data();
      map_keys.vh = map.cross_values_h[l].data();
    }
    if (!map.cross_keys_bf16.empty()) {
      map_keys.k_bf16 = &map.cross_keys_bf16[static_cast<size_t>(l) * c.heads];
      map_keys.v_bf16 = &map.cross_values_bf16[static_cast<size_t>(l) * c.heads];
    }
    if (l > 0 || static_cast<int>(computed.size()) == n) {
      x += relative_attention(layer_norm(x, L.cross_norm), L.cross, c.heads, map_keys, cross.per_query, pool_.get());
    } else if (!computed.empty()) {
      const Mat xc = layer_norm(x(computed, Eigen::all), L.cross_norm);
      x(computed, Eigen::all) +=
          relative_attention(xc, L.cross, c.heads, map_keys, cross_computed, pool_.get());
    }
    const Mat xs = layer_norm(x, L.self_norm);
    const Mat k = linear(xs, L.self.key), v = linear(xs, L.self.value);
    cache.write_keys(l, cache.size(), k.data(), n);
    cache.write_values(l, cache.size(), v.data(), n);
    const KeyValueRows kv = cache.half()
                                ? KeyValueRows(cache.kh[l].data(), cache.vh[l].data(), cache.capacity, c.d_model)
                                : KeyValueRows(MatMap(cache.k[l].data(), cache.capacity, c.d_model),
                                               MatMap(cache.v[l].data(), cache.capacity, c.d_model));
    if (l + 1 == c.decoder_layers) {
      // Every token's keys and values are in the cache now; what follows only shapes the outputs asked for.
      x = x(outputs, Eigen::all).eval();
      x += relative_attention(xs(outputs, Eigen::all), L.self, c.heads, kv, self_out, pool_.get());
    } else {
      x += relative_attention(xs, L.self, c.heads, kv, self.per_query, pool_.get());
    }
    Mat f = linear(layer_norm(x, L.ffn_norm), L.ffn1);
    relu_inplace(f);
    x += linear(f, L.ffn2);
  }
  cache.tokens.insert(cache.tokens.end(), tokens.begin(), tokens.end());
  for (const DecoderToken& t : tokens) cache.anchors.push_back(anchor_of(t));
  cache.next_seq += n;
  return layer_norm(x, decoder_final_norm_);
}

void Model::count_work(DecodeWork& w, const KeySets& self, const KeySets& cross, std::span<const int> outputs) const {
  const int layers = config().decoder_layers;
  auto reads = [](const QueryKeys* q) { return static_cast<int64_t>(q->keys.size()); };
  auto posed = [](const QueryKeys* q) { return static_cast<int64_t>(q->posed()); };
  const int64_t n = static_cast<int64_t>(self.per_query.size());
  ++w.calls;
  w.tokens += n;
  w.query_layers += n * (layers - 1) + static_cast<int64_t>(outputs.size());
  for (size_t i = 0; i < self.per_query.size(); ++i) {
    w.key_reads += reads(self.per_query[i]) * (layers - 1) + reads(cross.per_query[i]) * layers;
    w.posed_key_reads += posed(self.per_query[i]) * (layers - 1) + posed(cross.per_query[i]) * layers;
  }
  for (int i : outputs) {
    w.key_reads += reads(self.per_query[i]);
    w.posed_key_reads += posed(self.per_query[i]);
  }
  for (const auto& set : self.sets) w.relation_rows += set->posed();
  for (const auto& set : cross.sets) w.relation_rows += set->posed();
}

double Model::decode_flops(const DecodeWork& w) const {
  const ModelConfig& c = config();
  const double d = c.d_model, r = c.relation_dim, layers = c.decoder_layers;
  // Multiply-adds. Per token and layer: cross-attention's query side (Q, Q', output: 3 d^2; the relation query and
  // relation-value projection: 2 d r) and the self-attention keys and values (2 d^2). Per self-attention query and
  // layer: the same query side and the feed-forward (2 d * ffn). Per key read: q.k and a v (2 d); with relation
  // rows also u.h and a h (2 heads r). Per relation row: the MLP (7 r + r^2).
  const double token_layer = 3 * d * d + 2 * d * r + 2 * d * d;
  const double query_layer = 3 * d * d + 2 * d * r + 2 * d * c.ffn_dim();
  // Cross-attention queries taken from kept rows (position-less tokens' first layer) did no query-side work; their key
  // reads were not counted (decode).
  const double kept_query = 3 * d * d + 2 * d * r;
  const double macs = w.tokens * layers * token_layer - w.kept_cross_queries * kept_query +
                      w.query_layers * query_layer + w.key_reads * 2 * d + w.posed_key_reads * 2 * c.heads * r +
                      w.relation_rows * (kRelationFeatures * r + r * r);
  return 2 * macs;
}

Mat Model::decode_full(const MapContext& map, std::vector<DecoderToken>& tokens) const {
  KvCache cache = new_cache();
  return decode(map, cache, tokens);
}

}  // namespace ss
