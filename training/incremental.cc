#include "training/incremental.h"

#include "absl/strings/str_cat.h"
#include "engine/model/attention.h"
#include "engine/model/key_select.h"
#include "engine/sim/teacher_forcing.h"
#include "training/batch.h"

namespace ss::train {
namespace {

void add_keys(KeyLists& lists, const std::vector<int>& keys, const Anchor& q, auto key_anchor) {
  for (int j : keys) {
    lists.keys.push_back(j);
    const RelationFeatures f = relation_features(q, key_anchor(j));
    lists.features.insert(lists.features.end(), f.begin(), f.end());
  }
  lists.offsets.push_back(static_cast<int>(lists.keys.size()));
}

Anchor anchor_of(const DecoderToken& t) { return Anchor(t.has_pose, t.pose, t.step); }

}  // namespace

TorchDecoder::TorchDecoder(const TorchModel& model, std::vector<MapSegment> segments)
    : model_(model), segments_(std::move(segments)), index_(segments_) {
  torch::NoGradGuard no_grad;
  TeacherForcedExample map;
  map.segments = segments_;
  fill_map_inputs(map, model_.config());
  const Batch b = make_batch({&map});
  map_tokens_ = model_.encode_map(b);
  for (int l = 0; l < model_.config().decoder_layers; ++l) {
    const std::string C = absl::StrCat("decoder.layers.", l, ".cross_attn");
    cross_k_.push_back(model_.linear(map_tokens_, C + ".key"));
    cross_v_.push_back(model_.linear(map_tokens_, C + ".value"));
    k_.emplace_back();
    v_.emplace_back();
  }
}

torch::Tensor TorchDecoder::decode(std::vector<DecoderToken>& tokens) {
  torch::NoGradGuard no_grad;
  const ModelConfig& c = model_.config();
  const int n = static_cast<int>(tokens.size());
  for (int i = 0; i < n; ++i) tokens[i].seq = next_seq_ + i;
  next_seq_ += n;
  // Tokens older than the window are never read again (mask.h): drop them, as a session's cache does.
  size_t drop = 0;
  while (drop < cache_.size() && cache_[drop].step < tokens.front().step - c.window_steps + 1) ++drop;
  if (drop > 0) {
    cache_.erase(cache_.begin(), cache_.begin() + drop);
    for (int l = 0; l < c.decoder_layers; ++l) k_[l] = k_[l].slice(0, drop), v_[l] = v_[l].slice(0, drop);
  }

  // The step as a one-example batch: its tokens, keys into cached-then-new tokens, no targets.
  TeacherForcedExample ex;
  ex.tokens = tokens;
  for (auto* t : {&ex.light_target, &ex.motion_target, &ex.type_target, &ex.segment_target, &ex.end_target})
    t->assign(n, kNoTarget);
  std::array<int, kRsFields> none;
  none.fill(kNoTarget);
  ex.state_target.assign(n, none);
  const NeighbourLimit limit{c.knn_k, c.knn_radius, c.knn_always};
  SelfKeySelector selector(cache_, tokens, c.window_steps, limit);
  SelfKeys keys;
  const int cached = static_cast<int>(cache_.size());
  auto key_anchor = [&](int j) { return anchor_of(j < cached ? cache_[j] : tokens[j - cached]); };
  for (int i = 0; i < n; ++i) {
    selector.select(i, keys);
    std::vector<int> all = keys.posed;
    all.insert(all.end(), keys.unposed.begin(), keys.unposed.end());
    add_keys(ex.self_keys, all, anchor_of(tokens[i]), key_anchor);
    const DecoderToken& q = tokens[i];
    std::vector<int> near;
    if (q.has_pose) near = map_keys_near(segments_, index_, {q.pose.x, q.pose.y}, limit);
    add_keys(ex.cross_keys, near, Anchor(true, q.pose, 0), [&](int j) { return Anchor(true, segments_[j].pose, 0); });
  }
  const Batch b = make_batch({&ex});
  TorchModel::LayerInputs in;
  in.cross_k = cross_k_;
  in.cross_v = cross_v_;
  in.self_rel = model_.relation(b.self_features, "decoder.self_relation");
  in.cross_rel = model_.relation(b.cross_features, "decoder.cross_relation");
  in.rest = model_.relation(torch::zeros({1, kRelationFeatures}), "decoder.cross_relation");
  in.map_begin = {0, map_tokens_.size(0)};
  torch::Tensor x = model_.embed(b);
  for (int l = 0; l < c.decoder_layers; ++l) x = model_.decoder_layer(l, x, b, in, k_[l], v_[l], &k_[l], &v_[l]);
  cache_.insert(cache_.end(), tokens.begin(), tokens.end());
  return model_.norm(x, "decoder.final_norm");
}

}  // namespace ss::train
