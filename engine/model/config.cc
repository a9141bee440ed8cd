#include "engine/model/config.h"

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "engine/model/vocab.h"

namespace ss {

absl::StatusOr<ModelConfig> model_config_by_name(const std::string& name) {
  ModelConfig c;
  if (name == "large") return c;
  if (name == "small") {
    c.name = "small";
    c.d_model = 64;
    return c;
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown model configuration '", name, "' (use small or large)"));
}

absl::Status validate_config(const ModelConfig& c) {
  const std::pair<const char*, int> sizes[] = {
      {"d_model", c.d_model},         {"heads", c.heads},
      {"encoder_layers", c.encoder_layers}, {"decoder_layers", c.decoder_layers},
      {"ffn_mult", c.ffn_mult},       {"polyline_dim", c.polyline_dim},
      {"relation_dim", c.relation_dim}, {"rs_layers", c.rs_layers},
      {"max_map_segments", c.max_map_segments}, {"agent_slots", c.agent_slots},
      {"light_slots", c.light_slots}, {"knn_k", c.knn_k},
      {"knn_always", c.knn_always},   {"window_steps", c.window_steps}};
  for (const auto& [name, v] : sizes)
    if (v <= 0 || v > 1 << 16) return absl::InvalidArgumentError(absl::StrCat("model config ", name, " = ", v, " is out of range"));
  if (c.d_model > 4096 || c.ffn_mult > 16 || c.polyline_dim > 4096 || c.relation_dim > 4096)
    return absl::InvalidArgumentError("model config widths exceed 4096 (or ffn_mult 16)");
  if (c.d_model % c.heads != 0)
    return absl::InvalidArgumentError(absl::StrCat("model config d_model ", c.d_model, " is not divisible by heads ", c.heads));
  if (c.window_steps < 2)
    return absl::InvalidArgumentError("model config window_steps must be at least 2 (a step reads the previous step)");
  if (!(c.knn_radius > 0)) return absl::InvalidArgumentError("model config knn_radius must be positive");
  if (c.knn_always > c.knn_k) return absl::InvalidArgumentError("model config knn_always exceeds knn_k");
  return absl::OkStatus();
}

std::map<std::string, std::string> config_to_metadata(const ModelConfig& c) {
  return {{"format", "scenestreamer-weights-v1"},
          {"name", c.name},
          {"d_model", absl::StrCat(c.d_model)},
          {"heads", absl::StrCat(c.heads)},
          {"encoder_layers", absl::StrCat(c.encoder_layers)},
          {"decoder_layers", absl::StrCat(c.decoder_layers)},
          {"ffn_mult", absl::StrCat(c.ffn_mult)},
          {"polyline_dim", absl::StrCat(c.polyline_dim)},
          {"relation_dim", absl::StrCat(c.relation_dim)},
          {"rs_layers", absl::StrCat(c.rs_layers)},
          {"max_map_segments", absl::StrCat(c.max_map_segments)},
          {"agent_slots", absl::StrCat(c.agent_slots)},
          {"light_slots", absl::StrCat(c.light_slots)},
          {"knn_k", absl::StrCat(c.knn_k)},
          {"knn_radius", absl::StrCat(c.knn_radius)},
          {"knn_always", absl::StrCat(c.knn_always)},
          {"window_steps", absl::StrCat(c.window_steps)},
          {"motion_vocab", absl::StrCat(kMotionInputVocab)},
          {"state_bins", absl::StrCat(kRsBins)}};
}

absl::StatusOr<ModelConfig> config_from_metadata(const std::map<std::string, std::string>& m) {
  auto get = [&](const char* key) -> absl::StatusOr<std::string> {
    auto it = m.find(key);
    if (it == m.end()) return absl::InvalidArgumentError(absl::StrCat("weights __metadata__ lacks '", key, "'"));
    return it->second;
  };
  auto format = get("format");
  if (!format.ok()) return format.status();
  if (*format != "scenestreamer-weights-v1")
    return absl::InvalidArgumentError(absl::StrCat("weights __metadata__ format '", *format, "' is not scenestreamer-weights-v1"));
  ModelConfig c;
  auto name = get("name");
  if (!name.ok()) return name.status();
  c.name = *name;
  const std::pair<const char*, int*> ints[] = {
      {"d_model", &c.d_model},         {"heads", &c.heads},
      {"encoder_layers", &c.encoder_layers}, {"decoder_layers", &c.decoder_layers},
      {"ffn_mult", &c.ffn_mult},       {"polyline_dim", &c.polyline_dim},
      {"relation_dim", &c.relation_dim}, {"rs_layers", &c.rs_layers},
      {"max_map_segments", &c.max_map_segments}, {"agent_slots", &c.agent_slots},
      {"light_slots", &c.light_slots}, {"knn_k", &c.knn_k},
      {"knn_always", &c.knn_always},   {"window_steps", &c.window_steps}};
  for (const auto& [key, dst] : ints) {
    auto v = get(key);
    if (!v.ok()) return v.status();
    if (!absl::SimpleAtoi(*v, dst))
      return absl::InvalidArgumentError(absl::StrCat("weights __metadata__ ", key, " = '", *v, "' is not an integer"));
  }
  auto radius = get("knn_radius");
  if (!radius.ok()) return radius.status();
  if (!absl::SimpleAtod(*radius, &c.knn_radius))
    return absl::InvalidArgumentError(absl::StrCat("weights __metadata__ knn_radius = '", *radius, "' is not a number"));
  for (const auto& [key, want] : {std::pair{"motion_vocab", kMotionInputVocab}, std::pair{"state_bins", kRsBins}}) {
    auto v = get(key);
    int n = 0;
    if (!v.ok()) return v.status();
    if (!absl::SimpleAtoi(*v, &n) || n != want)
      return absl::InvalidArgumentError(absl::StrCat("weights __metadata__ ", key, " = '", *v, "', this engine needs ", want));
  }
  if (auto st = validate_config(c); !st.ok()) return st;
  return c;
}

namespace {

using Init = TensorSpec::Init;

struct SpecList {
  std::vector<TensorSpec> specs;
  void add(const std::string& name, std::vector<int64_t> shape, Init init = Init::normal) {
    specs.push_back({name, std::move(shape), init});
  }
  // y = W x + b with W [out, in].
  void linear(const std::string& name, int64_t out, int64_t in, bool bias = true) {
    add(name + ".weight", {out, in});
    if (bias) add(name + ".bias", {out}, Init::zeros);
  }
  void layer_norm(const std::string& name, int64_t d) {
    add(name + ".weight", {d}, Init::ones);
    add(name + ".bias", {d}, Init::zeros);
  }
  // Relative attention (docs/design.md section 7): content query/key/value/output, a relation query, and the per-layer
  // linear maps of the shared relation features h_ij into keys and values.
  void relative_attention(const std::string& name, int64_t d, int64_t r) {
    for (const char* p : {"query", "key", "value", "output", "rel_query"}) linear(name + "." + p, d, d);
    linear(name + ".rel_key", d, r);
    linear(name + ".rel_value", d, r);
  }
  void relation_mlp(const std::string& name, int64_t r) {
    linear(name + ".fc1", r, kRelationFeatures);
    linear(name + ".fc2", r, r);
  }
  void ffn(const std::string& name, int64_t d, int64_t f) {
    linear(name + ".fc1", f, d);
    linear(name + ".fc2", d, f);
  }
  // LN, Linear(no bias), LN, ReLU, Linear: the classification heads of the reference.
  void mlp_head(const std::string& name, int64_t d, int64_t classes) {
    layer_norm(name + ".norm1", d);
    linear(name + ".fc1", d, d, false);
    layer_norm(name + ".norm2", d);
    linear(name + ".fc2", classes, d);
  }
};

}  // namespace

std::vector<TensorSpec> model_parameter_specs(const ModelConfig& c) {
  const int64_t d = c.d_model, p = c.polyline_dim, r = c.relation_dim, f = c.ffn_dim();
  SpecList s;
  // Map encoder: PointNet over each segment's points, then transformer layers over segments.
  s.linear("encoder.polyline.fc1", p, kPointFeatures, false);
  s.layer_norm("encoder.polyline.norm1", p);
  s.linear("encoder.polyline.fc2", p, 2 * p);
  s.layer_norm("encoder.polyline.norm2", p);
  s.linear("encoder.polyline.fc3", p, p);
  s.linear("encoder.polyline.fc4", d, p);
  s.relation_mlp("encoder.relation", r);
  for (int l = 0; l < c.encoder_layers; ++l) {
    const std::string L = absl::StrCat("encoder.layers.", l);
    s.layer_norm(L + ".attn_norm", d);
    s.relative_attention(L + ".attn", d, r);
    s.layer_norm(L + ".ffn_norm", d);
    s.ffn(L + ".ffn", d, f);
  }
  s.layer_norm("encoder.final_norm", d);
  s.add("encoder.map_id_embedding", {c.max_map_segments, d});

  // Dynamic-token embeddings (summed per token; docs/design.md section 5).
  s.add("embed.agent_type", {kAgentTypes, d});
  s.add("embed.agent_slot", {c.agent_slots, d});
  s.add("embed.light_slot", {c.light_slots, d});
  s.add("embed.light_state", {kLightStates, d});
  s.add("embed.motion_action", {kMotionInputVocab, d});
  s.linear("embed.motion_state.fc1", d, kMotionStateFeatures);
  s.linear("embed.motion_state.fc2", d, d);
  s.add("embed.special", {kSpecialTokens, d});
  s.add("embed.intra_index", {4 * static_cast<int64_t>(c.agent_slots), d});
  s.linear("embed.relative_state.fc1", d, kRsFields);
  s.linear("embed.relative_state.fc2", d, d);

  // Decoder.
  s.relation_mlp("decoder.self_relation", r);
  s.relation_mlp("decoder.cross_relation", r);
  for (int l = 0; l < c.decoder_layers; ++l) {
    const std::string L = absl::StrCat("decoder.layers.", l);
    s.layer_norm(L + ".cross_norm", d);
    s.relative_attention(L + ".cross_attn", d, r);
    s.layer_norm(L + ".self_norm", d);
    s.relative_attention(L + ".self_attn", d, r);
    s.layer_norm(L + ".ffn_norm", d);
    s.ffn(L + ".ffn", d, f);
  }
  s.layer_norm("decoder.final_norm", d);

  // Heads.
  s.mlp_head("head.light", d, kLightStates);
  s.mlp_head("head.motion", d, kMotionVocab);
  s.linear("head.agent_type", kAgentTypes, d);
  s.linear("head.end_of_agents", 2, d);  // logits of (another agent, end of agents)
  s.linear("head.map_segment.query", d, d);
  s.linear("head.map_segment.key", d, d);
  s.add("head.relative_state.input_embedding", {kRsBins + 1, d});  // 81 bins + start
  s.add("head.relative_state.position_embedding", {kRsFields + 1, d});
  for (int b = 0; b < c.rs_layers; ++b) {
    const std::string B = absl::StrCat("head.relative_state.blocks.", b);
    // AdaLN modulation starts at zero so each block starts as a plain pre-LN block.
    s.add(B + ".adaln1.weight", {2 * d, d}, Init::zeros);
    s.add(B + ".adaln1.bias", {2 * d}, Init::zeros);
    for (const char* p : {"query", "key", "value", "output"}) s.linear(B + ".attn." + p, d, d);
    s.add(B + ".adaln2.weight", {2 * d, d}, Init::zeros);
    s.add(B + ".adaln2.bias", {2 * d}, Init::zeros);
    s.ffn(B + ".ffn", d, f);
  }
  s.add("head.relative_state.final_adaln.weight", {2 * d, d}, Init::zeros);
  s.add("head.relative_state.final_adaln.bias", {2 * d}, Init::zeros);
  s.linear("head.relative_state.output", kRsBins, d);
  return s.specs;
}

}  // namespace ss
