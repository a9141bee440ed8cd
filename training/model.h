// The SceneStreamer model in libtorch: the engine's model (engine/model) written as differentiable torch math, with
// the same parameter names and shapes (model_parameter_specs), so export is a copy and the engine loads the result.
// Inputs come from the engine's teacher-forced examples (batch.h): the trainer builds no tokens or key sets itself.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "engine/model/config.h"
#include "engine/model/weights.h"
#include "training/batch.h"

namespace ss::train {

struct Forward {
  torch::Tensor map_tokens;  // [M, d] over the batch's maps
  torch::Tensor hidden;      // [N, d] decoder outputs (after the final norm)
};

// Per-head logits on the tokens that read each head (rows as in Batch::heads).
struct HeadLogits {
  torch::Tensor light, motion, type, end;  // [rows, classes]
  std::vector<torch::Tensor> segment;      // per example: [TYPE rows of it, its map size]
  torch::Tensor state;                     // [MS rows, 8, 81]
};

class TorchModel {
 public:
  // Parameters from engine weights (e.g. init_weights(config, seed) or a loaded file).
  explicit TorchModel(const Weights& w);
  const ModelConfig& config() const { return config_; }
  std::vector<torch::Tensor> parameters() const;
  // Parameters of the first training stage's heads' complement: those only the agent-state heads use.
  bool is_agent_state_head(const std::string& name) const;
  const std::map<std::string, torch::Tensor>& named_parameters() const { return params_; }
  // The engine's weights (a copy of every tensor).
  Weights to_weights() const;

  Forward forward(const Batch& b) const;
  HeadLogits heads(const Batch& b, const Forward& f) const;

 private:
  friend class TorchDecoder;  // steps the same layers over its own cache (incremental.h)
  const torch::Tensor& p(const std::string& name) const;
  torch::Tensor linear(const torch::Tensor& x, const std::string& name, bool bias = true) const;
  torch::Tensor norm(const torch::Tensor& x, const std::string& name) const;
  torch::Tensor mlp_head(const torch::Tensor& h, const std::string& name) const;
  torch::Tensor relation(const torch::Tensor& features, const std::string& name) const;
  // Relative attention over sparse keys: the output projection of (weighted values + W_rv hbar + b_rv).
  torch::Tensor attention(const torch::Tensor& x, const std::string& name, const torch::Tensor& k,
                          const torch::Tensor& v, const torch::Tensor& rel, const SparseKeys& keys) const;
  torch::Tensor encode_map(const Batch& b) const;
  torch::Tensor embed(const Batch& b) const;
  // What every decoder layer reads besides the tokens: the map's keys and values per layer, the relation embeddings
  // of the batch's key lists, the relation row of a query without a position, and where each example's map starts.
  struct LayerInputs {
    std::vector<torch::Tensor> cross_k, cross_v;
    torch::Tensor self_rel, cross_rel, rest;
    std::vector<int64_t> map_begin;
  };
  LayerInputs layer_inputs(const Batch& b, const torch::Tensor& map_tokens, std::vector<int64_t> map_begin) const;
  // One decoder layer over the batch's tokens. Self-attention keys index `past_k` rows followed by the batch's own
  // (past_k undefined in training); the layer's keys and values of past and new tokens go to k_out and v_out.
  torch::Tensor decoder_layer(int l, const torch::Tensor& x, const Batch& b, const LayerInputs& in,
                              const torch::Tensor& past_k, const torch::Tensor& past_v, torch::Tensor* k_out,
                              torch::Tensor* v_out) const;
  torch::Tensor relative_state_logits(const torch::Tensor& z, const torch::Tensor& bins) const;

  ModelConfig config_;
  std::map<std::string, torch::Tensor> params_;
};

}  // namespace ss::train
