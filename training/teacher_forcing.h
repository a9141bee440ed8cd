// A scenario as the trainer sees it: the teacher-forced decoder tokens of its log (built by the same token builders
// as a session's steps), each token's target for each head, and the keys each query reads (token-group mask and
// nearest-neighbour limit applied, with the relation features of each pair). Only the differentiable math is left
// to the trainer, so there is one tokenizer and one token layout in the project.
#pragma once

#include <array>
#include <span>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "engine/map/spatial_index.h"
#include "engine/model/config.h"
#include "engine/model/token.h"
#include "engine/scenario/scenario.h"

namespace ss {

class Model;

struct TeacherForcingOptions {
  int phase = 0;               // 0..4: the 2 Hz steps take frames phase, phase + 5, ... (one log gives five sequences)
  int max_agents = 32;         // agents in the sequence: the SDC, the tracks to predict, then the nearest
  int max_map_segments = 0;    // 0: the model's; else at most this many (nearest the focus; memory per sample)
  double roi_radius = 100.0;   // metres around the SDC (or the focus): agents beyond it are not in the sequence
  uint64_t slot_seed = 0;      // 0: agent slots in order of entry, as a session allocates them; else a random draw
};

// Queries' keys in CSR form: query i reads keys[offsets[i] .. offsets[i + 1]), with 7 relation features per key.
struct KeyLists {
  std::vector<int> offsets{0};
  std::vector<int> keys;
  std::vector<float> features;  // keys.size() x kRelationFeatures

  int size() const { return static_cast<int>(keys.size()); }
};

inline constexpr int kNoTarget = -1;

struct TeacherForcedExample {
  std::string scenario_id;
  int phase = 0;
  int steps = 0;
  // The map: segments nearest the focus first; the encoder's input.
  std::vector<MapSegment> segments;
  std::vector<float> point_features;  // points x 27: every valid vector of every segment, segment by segment
  std::vector<int> point_segment;     // the segment of each point row
  KeyLists map_keys;                  // segment -> segments (encoder attention)
  // The decoder.
  std::vector<DecoderToken> tokens;   // sequence order (seq = index)
  KeyLists self_keys;                 // token -> earlier tokens (self-attention)
  KeyLists cross_keys;                // token -> segments; tokens without a position read every segment (empty here)
  // Targets per token (kNoTarget where the head is not read or the log has no answer).
  std::vector<int> light_target;      // light: its state at the next step
  std::vector<int> motion_target;     // motion: the token to the next step (0..1088)
  std::vector<int> type_target;       // SOA: the agent's type
  std::vector<int> segment_target;    // TYPE: the anchor segment (index into segments)
  std::vector<int> end_target;        // SOS and RS: 0 another agent follows, 1 end of agents (none when agents
                                      // beyond max_agents are in the region at that step)
  std::vector<std::array<int, kRsFields>> state_target;  // MS: the relative-state bins (all kNoTarget elsewhere)
  int agents = 0;                     // agents in the sequence
};

// Appends the key lists of the `fresh` tokens (one query each) as the decoder chooses them over `cached` then
// `fresh`: self-attention keys (indices into that sequence) and, for tokens with a position, their nearest
// segments. `index` is built over `segments`.
void append_decoder_keys(std::span<const DecoderToken> cached, std::span<const DecoderToken> fresh,
                         std::span<const MapSegment> segments, const SegmentIndex& index, const ModelConfig& config,
                         KeyLists& self, KeyLists& cross);

// The encoder's inputs of `ex.segments` (point_features, point_segment, map_keys), as Model::encode_map reads them.
void fill_map_inputs(TeacherForcedExample& ex, const ModelConfig& config);

// INVALID_ARGUMENT for a phase outside 0..4 or a scenario with fewer than two steps at that phase;
// FAILED_PRECONDITION for a map without segments.
absl::StatusOr<TeacherForcedExample> teacher_forced_example(const Scenario& scenario, const ModelConfig& config,
                                                            const TeacherForcingOptions& options);

// The same sequence with the agents' motion rolled out by `policy` (CAT-K, "closest among top-K", Zhang et al.
// 2025): from its first state each agent moves, step by step, by the one of the policy's `top_k` most probable
// motion tokens whose next box is nearest the log's, and its motion target at each step is re-tokenised: the
// token from its rolled-out state to the log's next pose. The agent set, the lights and their targets are the
// log's; the agent-state tokens and their targets describe the rolled-out states. INVALID_ARGUMENT for top_k < 1,
// and teacher_forced_example's errors.
absl::StatusOr<TeacherForcedExample> closed_loop_example(const Scenario& scenario, const Model& policy,
                                                         const TeacherForcingOptions& options, int top_k);

}  // namespace ss
