#include "training/model.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "engine/model/token.h"
#include "engine/model/vocab.h"

namespace ss::train {

namespace F = torch::nn::functional;

TorchModel::TorchModel(const Weights& w) : config_(w.config) {
  for (const TensorSpec& spec : model_parameter_specs(config_)) {
    const Tensor& t = w.at(spec.name);
    params_[spec.name] = torch::from_blob(const_cast<float*>(t.data.data()), spec.shape, torch::kFloat32)
                             .clone()
                             .set_requires_grad(true);
  }
}

std::vector<torch::Tensor> TorchModel::parameters() const {
  std::vector<torch::Tensor> out;
  for (const auto& [name, t] : params_) out.push_back(t);
  return out;
}

bool TorchModel::is_agent_state_head(const std::string& name) const {
  for (const char* prefix : {"head.agent_type.", "head.end_of_agents.", "head.map_segment.", "head.relative_state."})
    if (name.rfind(prefix, 0) == 0) return true;
  return false;
}

Weights TorchModel::to_weights() const {
  Weights w;
  w.config = config_;
  for (const auto& [name, t] : params_) {
    const torch::Tensor c = t.detach().contiguous();
    Tensor out;
    out.shape = c.sizes().vec();
    out.data.assign(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
    w.tensors[name] = std::move(out);
  }
  return w;
}

const torch::Tensor& TorchModel::p(const std::string& name) const {
  auto it = params_.find(name);
  TORCH_CHECK(it != params_.end(), "no parameter ", name);
  return it->second;
}

torch::Tensor TorchModel::linear(const torch::Tensor& x, const std::string& name, bool bias) const {
  return F::linear(x, p(name + ".weight"), bias ? p(name + ".bias") : torch::Tensor());
}

torch::Tensor TorchModel::norm(const torch::Tensor& x, const std::string& name) const {
  return F::layer_norm(x, F::LayerNormFuncOptions({x.size(-1)}).weight(p(name + ".weight")).bias(p(name + ".bias")).eps(1e-5));
}

torch::Tensor TorchModel::mlp_head(const torch::Tensor& h, const std::string& name) const {
  return linear(torch::relu(norm(linear(norm(h, name + ".norm1"), name + ".fc1", false), name + ".norm2")), name + ".fc2");
}

torch::Tensor TorchModel::relation(const torch::Tensor& features, const std::string& name) const {
  return torch::relu(linear(torch::relu(linear(features, name + ".fc1")), name + ".fc2"));
}

torch::Tensor TorchModel::attention(const torch::Tensor& x, const std::string& name, const torch::Tensor& k,
                                    const torch::Tensor& v, const torch::Tensor& rel, const SparseKeys& keys) const {
  const int heads = config_.heads, d = config_.d_model, dh = d / heads, r = config_.relation_dim;
  const torch::Tensor q = linear(x, name + ".query");
  const torch::Tensor q_rel = linear(x, name + ".rel_query");
  // u^h = q'^h W_rk^h: W_rk is [d, r], its rows h*dh .. (h+1)*dh belong to head h.
  const torch::Tensor w_rk = p(name + ".rel_key.weight").view({heads, dh, r});
  const torch::Tensor u = torch::einsum("nhd,hdr->nhr", {q_rel.view({-1, heads, dh}), w_rk}).reshape({-1, heads * r});
  auto [o, hbar] = sparse_attention(q, u, k, v, rel, keys, heads);
  const torch::Tensor w_rv = p(name + ".rel_value.weight").view({heads, dh, r});
  o = o + torch::einsum("nhr,hdr->nhd", {hbar.view({-1, heads, r}), w_rv}).reshape({-1, d}) + p(name + ".rel_value.bias");
  return linear(o, name + ".output");
}

torch::Tensor TorchModel::encode_map(const Batch& b) const {
  // PointNet: per-point MLP, max over the segment's points, concatenated back, MLP, max, MLP.
  const torch::Tensor mask = b.point_mask.unsqueeze(-1);
  const float neg = -std::numeric_limits<float>::infinity();
  torch::Tensor h1 = torch::relu(norm(linear(b.points, "encoder.polyline.fc1", false), "encoder.polyline.norm1"));
  const torch::Tensor pooled1 = h1.masked_fill(~mask, neg).amax(1, true);
  torch::Tensor h2 = torch::cat({h1, pooled1.expand_as(h1)}, -1);
  h2 = torch::relu(norm(linear(h2, "encoder.polyline.fc2"), "encoder.polyline.norm2"));
  const torch::Tensor pooled2 = h2.masked_fill(~mask, neg).amax(1);
  torch::Tensor x = linear(torch::relu(linear(pooled2, "encoder.polyline.fc3")), "encoder.polyline.fc4");

  const torch::Tensor rel = relation(b.map_features, "encoder.relation");
  for (int l = 0; l < config_.encoder_layers; ++l) {
    const std::string L = absl::StrCat("encoder.layers.", l);
    const torch::Tensor xn = norm(x, L + ".attn_norm");
    x = x + attention(xn, L + ".attn", linear(xn, L + ".attn.key"), linear(xn, L + ".attn.value"), rel, b.map_keys);
    x = x + linear(torch::relu(linear(norm(x, L + ".ffn_norm"), L + ".ffn.fc1")), L + ".ffn.fc2");
  }
  return norm(x, "encoder.final_norm") + p("encoder.map_id_embedding").index_select(0, b.map_row);
}

torch::Tensor TorchModel::embed(const Batch& b) const {
  auto is = [&](std::initializer_list<TokenKind> kinds) {
    torch::Tensor m = torch::zeros({b.tokens()}, torch::kBool);
    for (TokenKind k : kinds) m = m | (b.kind == static_cast<int64_t>(k));
    return m.unsqueeze(-1).to(torch::kFloat32);
  };
  auto rows = [&](const char* table, const torch::Tensor& index) { return p(table).index_select(0, index); };
  using K = TokenKind;
  const torch::Tensor light = is({K::light}), motion = is({K::motion}), rs = is({K::relative_state});
  const torch::Tensor member = is({K::soa, K::type, K::map_segment, K::relative_state});
  const torch::Tensor typed = is({K::type, K::map_segment, K::relative_state, K::motion});
  const torch::Tensor on_map = is({K::light, K::map_segment, K::relative_state});
  // SOS, EOS and SOA use rows 0, 1, 2 of embed.special.
  torch::Tensor special_row = torch::zeros({b.tokens()}, torch::kInt64);
  special_row.masked_fill_(b.kind == static_cast<int64_t>(K::eos), kSpecialEos);
  special_row.masked_fill_(b.kind == static_cast<int64_t>(K::soa), kSpecialSoa);
  const torch::Tensor special = is({K::sos, K::eos, K::soa});

  torch::Tensor x = light * (rows("embed.light_state", b.light_state) + rows("embed.light_slot", b.light_slot));
  x = x + on_map * rows("encoder.map_id_embedding", b.map_id);
  x = x + special * rows("embed.special", special_row);
  x = x + member * rows("embed.intra_index", b.intra);
  x = x + (member + motion) * rows("embed.agent_slot", b.agent_slot);
  x = x + typed * rows("embed.agent_type", b.agent_type);
  x = x + motion * (rows("embed.motion_action", b.motion_action) +
                    linear(torch::relu(linear(b.motion_state, "embed.motion_state.fc1")), "embed.motion_state.fc2"));
  x = x + rs * linear(torch::relu(linear(b.relative_state, "embed.relative_state.fc1")), "embed.relative_state.fc2");
  return x;
}

torch::Tensor TorchModel::decoder_layer(int l, const torch::Tensor& x, const Batch& b, const LayerInputs& in,
                                        const torch::Tensor& past_k, const torch::Tensor& past_v, torch::Tensor* k_out,
                                        torch::Tensor* v_out) const {
  const int d = config_.d_model, heads = config_.heads, dh = d / heads;
  const std::string L = absl::StrCat("decoder.layers.", l);
  const std::string C = L + ".cross_attn";
  const torch::Tensor& mk = in.cross_k[l];
  const torch::Tensor& mv = in.cross_v[l];
  const torch::Tensor xc = norm(x, L + ".cross_norm");
  torch::Tensor cross = attention(xc, C, mk, mv, in.cross_rel, b.cross_keys);  // rows without keys: replaced below
  // A query without a position reads its whole map with one relation row (features all zero): the row's score term
  // is the same for every key (the softmax cancels it), and its value term is added whole.
  for (int e = 0; e < b.examples; ++e) {
    const torch::Tensor& rows = b.unposed[e];
    if (rows.numel() == 0) continue;
    const int64_t m0 = in.map_begin[e], m1 = in.map_begin[e + 1];
    const torch::Tensor q = linear(xc.index_select(0, rows), C + ".query").view({-1, heads, dh}).transpose(0, 1);
    const torch::Tensor k = mk.slice(0, m0, m1).view({-1, heads, dh}).transpose(0, 1);
    const torch::Tensor v = mv.slice(0, m0, m1).view({-1, heads, dh}).transpose(0, 1);
    const torch::Tensor a = torch::softmax(torch::matmul(q, k.transpose(1, 2)) / std::sqrt(static_cast<float>(dh)), -1);
    const torch::Tensor o = torch::matmul(a, v).transpose(0, 1).reshape({-1, d}) + linear(in.rest, C + ".rel_value");
    cross = cross.index_copy(0, rows, linear(o, C + ".output"));
  }
  torch::Tensor y = x + cross;
  const torch::Tensor xs = norm(y, L + ".self_norm");
  torch::Tensor k = linear(xs, L + ".self_attn.key"), v = linear(xs, L + ".self_attn.value");
  if (past_k.defined()) k = torch::cat({past_k, k}), v = torch::cat({past_v, v});
  y = y + attention(xs, L + ".self_attn", k, v, in.self_rel, b.self_keys);
  if (k_out) *k_out = k, *v_out = v;
  return y + linear(torch::relu(linear(norm(y, L + ".ffn_norm"), L + ".ffn.fc1")), L + ".ffn.fc2");
}

TorchModel::LayerInputs TorchModel::layer_inputs(const Batch& b, const torch::Tensor& map_tokens,
                                                 std::vector<int64_t> map_begin) const {
  LayerInputs in;
  for (int l = 0; l < config_.decoder_layers; ++l) {
    const std::string C = absl::StrCat("decoder.layers.", l, ".cross_attn");
    in.cross_k.push_back(linear(map_tokens, C + ".key"));
    in.cross_v.push_back(linear(map_tokens, C + ".value"));
  }
  in.self_rel = relation(b.self_features, "decoder.self_relation");
  in.cross_rel = relation(b.cross_features, "decoder.cross_relation");
  in.rest = relation(torch::zeros({1, kRelationFeatures}), "decoder.cross_relation");
  in.map_begin = std::move(map_begin);
  return in;
}

Forward TorchModel::forward(const Batch& b) const {
  Forward f;
  f.map_tokens = encode_map(b);
  const LayerInputs in = layer_inputs(b, f.map_tokens, b.map_begin);
  torch::Tensor x = embed(b);
  for (int l = 0; l < config_.decoder_layers; ++l) x = decoder_layer(l, x, b, in, {}, {}, nullptr, nullptr);
  f.hidden = norm(x, "decoder.final_norm");
  return f;
}

torch::Tensor TorchModel::relative_state_logits(const torch::Tensor& z, const torch::Tensor& bins) const {
  // Position 0 reads START, position j the bin of field j - 1; position j predicts field j (causal).
  const int d = config_.d_model, heads = config_.heads, dh = d / heads;
  const int64_t n = z.size(0);
  const torch::Tensor start = torch::full({n, 1}, kRsBins, torch::kInt64);
  const torch::Tensor inputs = torch::cat({start, bins.slice(1, 0, kRsFields - 1)}, 1);  // [n, 8]
  torch::Tensor x = p("head.relative_state.input_embedding").index_select(0, inputs.reshape({-1})).view({n, kRsFields, d}) +
                    p("head.relative_state.position_embedding").slice(0, 0, kRsFields).unsqueeze(0);
  auto adaln = [&](const torch::Tensor& in, const std::string& name) {
    const torch::Tensor mod = linear(z, name).unsqueeze(1);  // [n, 1, 2d]: scale, then shift
    return F::layer_norm(in, F::LayerNormFuncOptions({d}).eps(1e-5)) * (1 + mod.slice(2, 0, d)) + mod.slice(2, d, 2 * d);
  };
  const torch::Tensor causal = torch::ones({kRsFields, kRsFields}, torch::kBool).triu(1);
  for (int blk = 0; blk < config_.rs_layers; ++blk) {
    const std::string B = absl::StrCat("head.relative_state.blocks.", blk);
    const torch::Tensor xn = adaln(x, B + ".adaln1");
    auto split = [&](const torch::Tensor& t) { return t.view({n, kRsFields, heads, dh}).transpose(1, 2); };
    const torch::Tensor q = split(linear(xn, B + ".attn.query")), k = split(linear(xn, B + ".attn.key")),
                        v = split(linear(xn, B + ".attn.value"));
    const torch::Tensor s = (torch::matmul(q, k.transpose(-1, -2)) / std::sqrt(static_cast<float>(dh)))
                                .masked_fill(causal, -std::numeric_limits<float>::infinity());
    const torch::Tensor o = torch::matmul(torch::softmax(s, -1), v).transpose(1, 2).reshape({n, kRsFields, d});
    x = x + linear(o, B + ".attn.output");
    x = x + linear(torch::relu(linear(adaln(x, B + ".adaln2"), B + ".ffn.fc1")), B + ".ffn.fc2");
  }
  return linear(adaln(x, "head.relative_state.final_adaln"), "head.relative_state.output");  // [n, 8, 81]
}

HeadLogits TorchModel::heads(const Batch& b, const Forward& f) const {
  HeadLogits out;
  const torch::Tensor& h = f.hidden;
  out.light = mlp_head(h.index_select(0, b.light_rows), "head.light");
  out.motion = mlp_head(h.index_select(0, b.motion_rows), "head.motion");
  out.type = linear(h.index_select(0, b.type_rows), "head.agent_type");
  out.end = linear(h.index_select(0, b.end_rows), "head.end_of_agents");
  const torch::Tensor pointer_keys = linear(f.map_tokens, "head.map_segment.key");
  const float scale = 1.0f / std::sqrt(static_cast<float>(config_.d_model));
  for (int e = 0; e < b.examples; ++e) {
    const torch::Tensor q = linear(h.index_select(0, b.segment_rows[e]), "head.map_segment.query");
    out.segment.push_back(torch::matmul(q, pointer_keys.slice(0, b.map_begin[e], b.map_begin[e + 1]).t()) * scale);
  }
  out.state = relative_state_logits(h.index_select(0, b.state_rows), b.state_target);
  return out;
}

}  // namespace ss::train
