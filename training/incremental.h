// The torch model stepped as a session steps the engine's: new tokens only, over its own cache of keys and values,
// with the same key selection (SelfKeySelector) and the same sparse attention as training, without gradients. It is
// what the engine is measured against (bench/torch_step_bench), not a serving path.
#pragma once

#include <vector>

#include <torch/torch.h>

#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/model/token.h"
#include "training/model.h"

namespace ss::train {

class TorchDecoder {
 public:
  // Encodes the map once (as MapContext does for the engine).
  TorchDecoder(const TorchModel& model, std::vector<MapSegment> segments);
  // Decodes `tokens` (one session's next tokens, sequence order) over the cache and appends them; returns their
  // final hidden states [n, d].
  torch::Tensor decode(std::vector<DecoderToken>& tokens);
  int cached_tokens() const { return static_cast<int>(cache_.size()); }

 private:
  const TorchModel& model_;
  std::vector<MapSegment> segments_;
  SegmentIndex index_;
  torch::Tensor map_tokens_;
  std::vector<torch::Tensor> cross_k_, cross_v_;  // per layer, [M, d]
  std::vector<DecoderToken> cache_;
  std::vector<torch::Tensor> k_, v_;              // per layer, [cached, d]
  int64_t next_seq_ = 0;
};

}  // namespace ss::train
