// The model's parameters and their file: safetensors (https://github.com/huggingface/safetensors), so the libtorch
// trainer and Python tools read and write the same file. Layout: an 8-byte little-endian header length N, N bytes of
// JSON header, then the raw little-endian float32 data. The header's "__metadata__" holds the ModelConfig
// (config_to_metadata); every other key is a tensor {"dtype": "F32", "shape": [...], "data_offsets": [begin, end]}
// with offsets relative to the data section. model_parameter_specs(config) is the contract: the loader accepts a
// file only if it holds exactly those tensors with exactly those shapes, all finite.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "engine/model/config.h"

namespace ss {

// A row-major float32 tensor; data.size() is the product of shape.
struct Tensor {
  std::vector<int64_t> shape;
  std::vector<float> data;
  bool operator==(const Tensor&) const = default;
};

struct Weights {
  ModelConfig config;
  std::map<std::string, Tensor> tensors;

  // The loader guarantees every parameter of the config is present, so a missing name is a programming error: aborts
  // with the name printed.
  const Tensor& at(const std::string& name) const;
  // Total number of floats over all tensors.
  int64_t parameter_count() const;
  bool operator==(const Weights&) const = default;
};

// A file's header may not exceed this; real headers are tens of kilobytes.
inline constexpr uint64_t kMaxWeightsHeaderBytes = uint64_t{100} << 20;

// Random weights for every parameter of `config`: N(0, 0.02), ones or zeros per TensorSpec::init. Each tensor's values
// depend only on the seed and its name, and are the same bytes on every run (the generator is our own, not the
// standard library's distributions, whose output differs between implementations).
Weights init_weights(const ModelConfig& config, uint64_t seed);

// Checks weights built in memory against the contract (the config's parameters, shapes, sizes, finite values).
// INVALID_ARGUMENT naming `where` and the tensor.
absl::Status validate_weights(const Weights& w, const std::string& where);

// Parses a weight file's bytes. Any defect is INVALID_ARGUMENT with a message "<where>: ..." naming the tensor
// concerned; no input crashes it.
absl::StatusOr<Weights> parse_weights(std::string_view bytes, const std::string& where);
// Reads and parses a file; NOT_FOUND if it does not exist.
absl::StatusOr<Weights> load_weights(const std::string& path);

// The file's bytes: tensors in name order, contiguous; the header padded with spaces to a multiple of 8 bytes so the
// data section is 8-byte aligned.
std::string serialize_weights(const Weights& w);
// Validates, then writes through a temporary file renamed into place, so a reader never sees half a file.
absl::Status save_weights(const std::string& path, const Weights& w);

}  // namespace ss
