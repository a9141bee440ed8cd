// The model's configuration: sizes, vocabularies and the attention neighbourhood. Stored in the weight file's
// __metadata__ so a file always says what it holds.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace ss {

struct ModelConfig {
  std::string name = "large";
  int d_model = 128;
  int heads = 4;
  int encoder_layers = 2;
  int decoder_layers = 4;
  int ffn_mult = 4;            // feed-forward width = ffn_mult * d_model
  int polyline_dim = 64;       // PointNet width
  int relation_dim = 32;       // width of the relation MLP h_ij (folded into queries, docs/design.md section 7)
  int rs_layers = 3;           // relative-state head: AdaLN transformer blocks
  int max_map_segments = 3000; // map-id embedding slots
  int agent_slots = 128;       // agent-id embedding slots, recycled after an agent retires
  int light_slots = 64;        // light-id embedding slots
  int knn_k = 128;             // at most this many spatial keys per query
  double knn_radius = 50.0;    // metres
  int knn_always = 8;          // the nearest keys kept whatever their distance
  int window_steps = 10;       // a token sees its own object's history at most this many steps back (cache window)

  int head_dim() const { return d_model / heads; }
  int ffn_dim() const { return ffn_mult * d_model; }
  bool operator==(const ModelConfig&) const = default;
};

// "small" (d 64) or "large" (d 128, paper appendix E); INVALID_ARGUMENT otherwise.
absl::StatusOr<ModelConfig> model_config_by_name(const std::string& name);
// Checks the sizes make sense (positive, d_model divisible by heads, window >= 2, ...).
absl::Status validate_config(const ModelConfig& c);

// The weight file's __metadata__ (string to string, as safetensors requires) and back.
std::map<std::string, std::string> config_to_metadata(const ModelConfig& c);
absl::StatusOr<ModelConfig> config_from_metadata(const std::map<std::string, std::string>& m);

// Every parameter tensor of the model, by name and shape (row-major; a Linear's weight is [out, in]).
// Names are stable: the libtorch trainer uses the same names, and the loader checks every one.
struct TensorSpec {
  std::string name;
  std::vector<int64_t> shape;
  enum class Init { normal, zeros, ones } init = Init::normal;  // what init-weights writes
};
std::vector<TensorSpec> model_parameter_specs(const ModelConfig& c);

}  // namespace ss
