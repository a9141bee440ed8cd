// Which keys each query reads: the token-group mask and the nearest-neighbour limit, apart from any weights. The
// decoder uses it for its sessions and the trainer for its teacher-forced sequences, so both read the same keys.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "engine/map/segments.h"
#include "engine/map/spatial_index.h"
#include "engine/model/mask.h"
#include "engine/model/token.h"

namespace ss {

// One query's self-attention keys, as indices into the cached tokens followed by the fresh ones, each part ascending.
struct SelfKeys {
  std::vector<int> posed;    // a position on both sides: these get their own relation columns
  std::vector<int> unposed;  // a side without a position: the relation depends on the step difference only
};

class SelfKeySelector {
 public:
  // `cached` then `fresh` is the sequence (seq assigned, sequence order); the spans must outlive the selector.
  SelfKeySelector(std::span<const DecoderToken> cached, std::span<const DecoderToken> fresh, int window_steps,
                  const NeighbourLimit& limit);
  // The keys fresh token `i` reads.
  void select(int i, SelfKeys& out);

 private:
  // A step's tokens by the lists a query reads, each ascending. Only what a fresh token can read is listed: lights
  // and groups at the fresh tokens' steps, motion from the step before, bounds back to the window's start.
  struct Step {
    std::vector<int> lights, group, motion;
    std::vector<int> bounds;  // the group's SOS and EOS (also in `group`)
  };
  const DecoderToken& token(int j) const { return j < cached_size_ ? cached_[j] : fresh_[j - cached_size_]; }
  const Step* at(int step) const;

  std::span<const DecoderToken> cached_, fresh_;
  int cached_size_ = 0;
  int window_ = 0;
  NeighbourLimit limit_;
  int first_step_ = 0;                           // the step of steps_[0]
  std::vector<Step> steps_;                      // by step - first_step_
  std::vector<int64_t> objects_;                 // the fresh tokens' objects, ascending, each once
  std::vector<std::vector<int>> object_tokens_;  // by position in objects_: that object's tokens, ascending
  std::vector<uint64_t> posed_bits_, unposed_bits_;  // one query's kept keys by index (emitted in order, cleared)
  std::vector<int> spatial_, kept_, outside_;
  std::vector<double> dist_;
  std::vector<int64_t> order_;
};

// The map tokens a query at `p` reads in cross-attention (and a segment reads in the encoder): its nearest segments
// within the limit, as ascending segment indices.
std::vector<int> map_keys_near(std::span<const MapSegment> segments, const SegmentIndex& index, Vec2 p,
                               const NeighbourLimit& limit);

}  // namespace ss
