#include "training/incremental.h"

#include "absl/strings/str_cat.h"
#include "training/teacher_forcing.h"
#include "training/batch.h"

namespace ss::train {

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
  append_decoder_keys(cache_, tokens, segments_, index_, c, ex.self_keys, ex.cross_keys);
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
