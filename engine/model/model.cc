// Model construction (parameter lookup), the map encoder and the heads. The decoder is in decoder.cc.
#include "engine/model/model.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "engine/model/attention_kernels.h"
#include "engine/model/key_select.h"
#include "engine/model/matmul_bf16.h"

namespace ss {

absl::StatusOr<MatmulPrecision> matmul_precision_by_name(const std::string& name) {
  if (name == "fp32") return MatmulPrecision::fp32;
  if (name == "bf16") return MatmulPrecision::bf16;
  return absl::InvalidArgumentError(absl::StrCat("unknown matmul precision '", name, "' (use fp32 or bf16)"));
}

const char* matmul_precision_name(MatmulPrecision p) { return p == MatmulPrecision::bf16 ? "bf16" : "fp32"; }

absl::StatusOr<KvPrecision> kv_precision_by_name(const std::string& name) {
  if (name == "fp32") return KvPrecision::fp32;
  if (name == "fp16") return KvPrecision::fp16;
  return absl::InvalidArgumentError(absl::StrCat("unknown KV precision '", name, "' (use fp32 or fp16)"));
}

const char* kv_precision_name(KvPrecision p) { return p == KvPrecision::fp16 ? "fp16" : "fp32"; }

Model::Model(Weights w, ModelOptions options) : weights_(std::move(w)), options_(options) {
  // The caller is one of the step's threads: the pool adds the others.
  if (options_.step_threads > 1) pool_ = std::make_unique<ThreadPool>(options_.step_threads - 1);
  const ModelConfig& c = weights_.config;
  limit_ = {c.knn_k, c.knn_radius, c.knn_always};
  poly_fc1_ = lin("encoder.polyline.fc1", false);
  poly_norm1_ = norm("encoder.polyline.norm1");
  poly_fc2_ = lin("encoder.polyline.fc2");
  poly_norm2_ = norm("encoder.polyline.norm2");
  poly_fc3_ = lin("encoder.polyline.fc3");
  poly_fc4_ = lin("encoder.polyline.fc4");
  encoder_relation_ = {lin("encoder.relation.fc1"), lin("encoder.relation.fc2")};
  for (int l = 0; l < c.encoder_layers; ++l) {
    const std::string L = absl::StrCat("encoder.layers.", l);
    encoder_layers_.push_back({norm(L + ".attn_norm"), norm(L + ".ffn_norm"), attn(L + ".attn"),
                               lin(L + ".ffn.fc1"), lin(L + ".ffn.fc2")});
  }
  encoder_final_norm_ = norm("encoder.final_norm");
  map_id_embedding_ = weights_.at("encoder.map_id_embedding").data.data();

  agent_type_emb_ = weights_.at("embed.agent_type").data.data();
  agent_slot_emb_ = weights_.at("embed.agent_slot").data.data();
  light_slot_emb_ = weights_.at("embed.light_slot").data.data();
  light_state_emb_ = weights_.at("embed.light_state").data.data();
  motion_action_emb_ = weights_.at("embed.motion_action").data.data();
  special_emb_ = weights_.at("embed.special").data.data();
  intra_emb_ = weights_.at("embed.intra_index").data.data();
  motion_state_fc1_ = lin("embed.motion_state.fc1");
  motion_state_fc2_ = lin("embed.motion_state.fc2");
  rs_embed_fc1_ = lin("embed.relative_state.fc1");
  rs_embed_fc2_ = lin("embed.relative_state.fc2");

  self_relation_ = {lin("decoder.self_relation.fc1"), lin("decoder.self_relation.fc2")};
  cross_relation_ = {lin("decoder.cross_relation.fc1"), lin("decoder.cross_relation.fc2")};
  self_relation_by_step_ = relation_by_step(self_relation_, c.window_steps);
  cross_relation_at_rest_ = relation_by_step(cross_relation_, 1);
  for (int l = 0; l < c.decoder_layers; ++l) {
    const std::string L = absl::StrCat("decoder.layers.", l);
    decoder_layers_.push_back({norm(L + ".cross_norm"), norm(L + ".self_norm"), norm(L + ".ffn_norm"),
                               attn(L + ".cross_attn"), attn(L + ".self_attn"), lin(L + ".ffn.fc1"),
                               lin(L + ".ffn.fc2")});
  }
  decoder_final_norm_ = norm("decoder.final_norm");

  light_head_ = mlp_head("head.light");
  motion_head_ = mlp_head("head.motion");
  agent_type_head_ = lin("head.agent_type");
  end_of_agents_head_ = lin("head.end_of_agents");
  pointer_query_ = lin("head.map_segment.query");
  pointer_key_ = lin("head.map_segment.key");
  rs_input_emb_ = weights_.at("head.relative_state.input_embedding").data.data();
  rs_position_emb_ = weights_.at("head.relative_state.position_embedding").data.data();
  for (int b = 0; b < c.rs_layers; ++b) {
    const std::string B = absl::StrCat("head.relative_state.blocks.", b);
    rs_blocks_.push_back({lin(B + ".adaln1"), lin(B + ".adaln2"), lin(B + ".attn.query"), lin(B + ".attn.key"),
                          lin(B + ".attn.value"), lin(B + ".attn.output"), lin(B + ".ffn.fc1"),
                          lin(B + ".ffn.fc2")});
  }
  rs_final_adaln_ = lin("head.relative_state.final_adaln");
  rs_output_ = lin("head.relative_state.output");
}

absl::StatusOr<std::shared_ptr<const Model>> Model::create(Weights weights, ModelOptions options) {
  if (auto st = validate_config(weights.config); !st.ok()) return st;
  // The weight loader checked every tensor against model_parameter_specs; a Weights built in memory is checked here.
  for (const TensorSpec& spec : model_parameter_specs(weights.config)) {
    auto it = weights.tensors.find(spec.name);
    if (it == weights.tensors.end()) return absl::InvalidArgumentError(absl::StrCat("weights lack tensor ", spec.name));
    if (it->second.shape != spec.shape)
      return absl::InvalidArgumentError(absl::StrCat("weights tensor ", spec.name, " has the wrong shape"));
  }
  if (options.step_threads < 1 || options.step_threads > 64)
    return absl::InvalidArgumentError(absl::StrCat("step threads must be 1 to 64, not ", options.step_threads));
  if (!options.kv_precision) options.kv_precision = KvPrecision::fp16;
  // bf16 where the CPU has AVX512-BF16 (with or without AMX), else fp32.
  if (!options.matmul_precision)
    options.matmul_precision = bf16_products_available() ? MatmulPrecision::bf16 : MatmulPrecision::fp32;
  if (*options.matmul_precision == MatmulPrecision::bf16 && !bf16_products_available())
    return absl::FailedPreconditionError(
        "matmul precision bf16 needs a CPU with AVX512-BF16 (Intel Cooper Lake or Sapphire Rapids and later, AMD Zen "
        "4 and later); this one has not: use fp32");
  return std::shared_ptr<const Model>(new Model(std::move(weights), options));
}

LinearParams Model::lin(const std::string& name, bool bias, bool through_linear) {
  const Tensor& w = weights_.at(name + ".weight");
  LinearParams p;
  p.weight = w.data.data();
  p.out = static_cast<int>(w.shape[0]);
  p.in = static_cast<int>(w.shape[1]);
  if (bias) p.bias = weights_.at(name + ".bias").data.data();
  if (through_linear && matmul_precision() == MatmulPrecision::bf16 && bf16_packable(p.out, p.in)) {
    bf16_weights_.push_back(std::make_unique<const Bf16Weight>(bf16_pack(p.weight, p.out, p.in)));
    p.bf16 = bf16_weights_.back().get();
  }
  return p;
}

NormParams Model::norm(const std::string& name) const {
  const Tensor& w = weights_.at(name + ".weight");
  return {w.data.data(), weights_.at(name + ".bias").data.data(), static_cast<int>(w.shape[0])};
}

AttentionParams Model::attn(const std::string& name) {
  return {lin(name + ".query"),     lin(name + ".key"),     lin(name + ".value"),    lin(name + ".output"),
          lin(name + ".rel_query"), lin(name + ".rel_key", true, false), lin(name + ".rel_value", true, false)};
}

MlpHeadParams Model::mlp_head(const std::string& name) {
  return {norm(name + ".norm1"), norm(name + ".norm2"), lin(name + ".fc1", false), lin(name + ".fc2")};
}

size_t MapContext::bytes() const {
  size_t b = tokens.size() + pointer_keys.size();
  for (const Mat& m : cross_keys) b += m.size();
  for (const Mat& m : cross_values) b += m.size();
  b *= sizeof(float);
  for (const auto* tiles : {&cross_keys_bf16, &cross_values_bf16})
    for (const Bf16Weight& w : *tiles) b += w.tiles.size() * sizeof(uint16_t);
  for (const auto* halves : {&cross_keys_h, &cross_values_h})
    for (const std::vector<uint16_t>& h : *halves) b += h.size() * sizeof(uint16_t);
  for (const MapSegment& s : segments) b += sizeof(MapSegment) + s.points.capacity() * sizeof(MapPoint);
  return b + sizeof(*this) + index.bytes() + anchors.capacity() * sizeof(Anchor);
}

namespace {

std::vector<uint16_t> halves_of(const Mat& m) {
  std::vector<uint16_t> h(static_cast<size_t>(m.size()));
  floats_to_halves(m.data(), static_cast<int>(m.size()), h.data());
  return h;
}

}  // namespace

absl::StatusOr<std::shared_ptr<const MapContext>> Model::encode_map(std::vector<MapSegment> segments) const {
  const ModelConfig& c = config();
  if (segments.empty()) return absl::FailedPreconditionError("the map has no segments: nothing to place agents on");
  if (static_cast<int>(segments.size()) > c.max_map_segments) segments.resize(c.max_map_segments);
  auto map = std::make_shared<MapContext>(std::move(segments));
  const int m = map->size();

  // PointNet, batched over the valid vectors of every segment.
  std::vector<int> owner;  // segment of each stacked vector
  std::vector<SegmentFeatures> features(m);
  for (int i = 0; i < m; ++i) {
    features[i] = segment_point_features(map->segments[i]);
    const int n = std::min(map->segments[i].num_vectors(), kMaxVectorsPerSegment);
    for (int v = 0; v < n; ++v) owner.push_back(i);
  }
  Mat points(owner.size(), kPointFeatures);
  for (size_t r = 0, i = 0; i < static_cast<size_t>(m); ++i) {
    const int n = std::min(map->segments[i].num_vectors(), kMaxVectorsPerSegment);
    for (int v = 0; v < n; ++v, ++r)
      points.row(r) = VecMap(features[i].data() + v * kPointFeatureDim, kPointFeatureDim);
  }
  auto segment_max = [&](const Mat& x) {
    Mat pooled = Mat::Constant(m, x.cols(), -std::numeric_limits<float>::infinity());
    for (size_t r = 0; r < owner.size(); ++r) pooled.row(owner[r]) = pooled.row(owner[r]).cwiseMax(x.row(r));
    return pooled;
  };
  Mat h1 = layer_norm(linear(points, poly_fc1_), poly_norm1_);
  relu_inplace(h1);
  const Mat pooled1 = segment_max(h1);
  Mat cat(owner.size(), 2 * c.polyline_dim);
  for (size_t r = 0; r < owner.size(); ++r) cat.row(r) << h1.row(r), pooled1.row(owner[r]);
  Mat h2 = layer_norm(linear(cat, poly_fc2_), poly_norm2_);
  relu_inplace(h2);
  Mat h3 = linear(segment_max(h2), poly_fc3_);
  relu_inplace(h3);
  Mat x = linear(h3, poly_fc4_);

  // Transformer layers over segments, each reading its nearest segments. The anchors (a pose with its heading's
  // cosine and sine) are made once per segment, not once per pair.
  for (const MapSegment& seg : map->segments) map->anchors.emplace_back(true, seg.pose, 0);
  std::vector<QueryKeys> keys(m);
  std::vector<const QueryKeys*> key_ptrs;
  for (const QueryKeys& k : keys) key_ptrs.push_back(&k);
  for (int i = 0; i < m; ++i) {
    const Pose& p = map->segments[i].pose;
    keys[i].keys = map_keys_near(map->segments, map->index, {p.x, p.y}, limit_);
    Mat f(keys[i].keys.size(), kRelationFeatures);
    for (size_t j = 0; j < keys[i].keys.size(); ++j) {
      const RelationFeatures rf = relation_features(map->anchors[i], map->anchors[keys[i].keys[j]]);
      for (int col = 0; col < kRelationFeatures; ++col) f(j, col) = rf[col];
    }
    keys[i].relation = relation_columns(f, encoder_relation_);
  }
  for (const EncoderLayerParams& L : encoder_layers_) {
    const Mat xn = layer_norm(x, L.attn_norm);
    const Mat k = linear(xn, L.attn.key), v = linear(xn, L.attn.value);
    x += relative_attention(xn, L.attn, c.heads, MatMap(k.data(), m, c.d_model), MatMap(v.data(), m, c.d_model), key_ptrs);
    Mat f = linear(layer_norm(x, L.ffn_norm), L.ffn1);
    relu_inplace(f);
    x += linear(f, L.ffn2);
  }
  map->tokens = layer_norm(x, encoder_final_norm_) + MatMap(map_id_embedding_, m, c.d_model);
  const int dh = c.d_model / c.heads;
  for (const DecoderLayerParams& L : decoder_layers_) {
    map->cross_keys.push_back(linear(map->tokens, L.cross.key));
    map->cross_values.push_back(linear(map->tokens, L.cross.value));
    if (kv_precision() == KvPrecision::fp16) {
      map->cross_keys_h.push_back(halves_of(map->cross_keys.back()));
      map->cross_values_h.push_back(halves_of(map->cross_values.back()));
    }
    if (matmul_precision() != MatmulPrecision::bf16) continue;
    for (int h = 0; h < c.heads; ++h) {
      map->cross_keys_bf16.push_back(bf16_pack(map->cross_keys.back().data() + h * dh, m, dh, c.d_model, 1));
      map->cross_values_bf16.push_back(bf16_pack(map->cross_values.back().data() + h * dh, dh, m, 1, c.d_model));
    }
    // With both, a layer past the first never reads its floats (queries with keys of their own read the halves, the
    // whole map's queries the tiles): dropped, a quarter to a third of a map's memory. The first layer's stay for
    // the kept rows, computed in floats (decode).
    if (map->cross_keys.size() > 1 && !map->cross_keys_h.empty()) {
      map->cross_keys.back() = Mat();
      map->cross_values.back() = Mat();
    }
  }
  map->pointer_keys = linear(map->tokens, pointer_key_);
  return std::shared_ptr<const MapContext>(std::move(map));
}

Mat Model::mlp_head_forward(const Mat& h, const MlpHeadParams& p) const {
  Mat x = layer_norm(linear(layer_norm(h, p.norm1), p.fc1), p.norm2);
  relu_inplace(x);
  return linear(x, p.fc2);
}

Mat Model::light_logits(const Mat& h) const { return mlp_head_forward(h, light_head_); }
Mat Model::motion_logits(const Mat& h) const { return mlp_head_forward(h, motion_head_); }
Mat Model::agent_type_logits(const Mat& h) const { return linear(h, agent_type_head_); }
Mat Model::end_of_agents_logits(const Mat& h) const { return linear(h, end_of_agents_head_); }

Mat Model::map_segment_logits(const Mat& h, const MapContext& map) const {
  const float scale = 1.0f / std::sqrt(static_cast<float>(config().d_model));
  return (linear(h, pointer_query_) * map.pointer_keys.transpose()) * scale;
}

RsHead Model::rs_begin(const Mat& z) const {
  const int d = config().d_model;
  RsHead s;
  // z is the same for every field: its AdaLN modulations (1 x 2d each: scale then shift) are computed once.
  for (const RsBlockParams& B : rs_blocks_) {
    s.modulation.push_back(linear(z, B.adaln1));
    s.modulation.push_back(linear(z, B.adaln2));
  }
  s.modulation.push_back(linear(z, rs_final_adaln_));
  s.keys.assign(rs_blocks_.size(), Mat(kRsFields, d));
  s.values.assign(rs_blocks_.size(), Mat(kRsFields, d));
  return s;
}

Vec Model::rs_next(RsHead& s, int previous_bin) const {
  const int d = config().d_model, heads = config().heads, dh = d / heads;
  const int j = s.fields;  // this row's position: the start token, then one row per field so far
  const int input = j == 0 ? kRsBins : previous_bin;
  Mat x = VecMap(rs_input_emb_ + input * d, d) + VecMap(rs_position_emb_ + j * d, d);
  // AdaLN: LayerNorm without affine, scaled by (1 + g(z)) and shifted by b(z).
  auto adaln = [d](const Mat& in, const Mat& mod) {
    Mat y = layer_norm_plain(in);
    y.array() *= mod.leftCols(d).array() + 1.0f;
    y += mod.rightCols(d);
    return y;
  };
  const float scale = 1.0f / std::sqrt(static_cast<float>(dh));
  for (size_t b = 0; b < rs_blocks_.size(); ++b) {
    const RsBlockParams& B = rs_blocks_[b];
    const Mat xn = adaln(x, s.modulation[2 * b]);
    const Mat q = linear(xn, B.query);
    s.keys[b].row(j) = linear(xn, B.key);
    s.values[b].row(j) = linear(xn, B.value);
    Mat o(1, d);
    Vec w(j + 1);
    for (int h = 0; h < heads; ++h) {  // causal: this row reads rows 0..j
      for (int i = 0; i <= j; ++i) w[i] = q.row(0).segment(h * dh, dh).dot(s.keys[b].row(i).segment(h * dh, dh)) * scale;
      softmax_inplace(w.data(), j + 1);
      o.row(0).segment(h * dh, dh) = w * s.values[b].block(0, h * dh, j + 1, dh);
    }
    x += linear(o, B.output);
    Mat f = linear(adaln(x, s.modulation[2 * b + 1]), B.ffn1);
    relu_inplace(f);
    x += linear(f, B.ffn2);
  }
  ++s.fields;
  return linear(adaln(x, s.modulation.back()), rs_output_);
}

Vec Model::relative_state_logits(const Mat& z, std::span<const int> prefix) const {
  RsHead s = rs_begin(z);
  Vec logits = rs_next(s, 0);
  for (int bin : prefix) logits = rs_next(s, bin);
  return logits;
}

}  // namespace ss
