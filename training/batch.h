// Teacher-forced examples (training/teacher_forcing.h) as tensors: several examples concatenated into one batch
// (their maps and sequences side by side, key indices offset), which is what the torch model reads.
#pragma once

#include <vector>

#include <torch/torch.h>

#include "training/teacher_forcing.h"
#include "training/sparse_attention.h"

namespace ss::train {

struct Batch {
  int examples = 0;
  // Maps: M segments over the batch.
  torch::Tensor points;        // float [M, 30, 27]: each segment's vectors, zero past its last
  torch::Tensor point_mask;    // bool [M, 30]
  torch::Tensor map_row;       // int64 [M]: the segment's index in its own map (its map-id embedding row)
  SparseKeys map_keys;         // segment -> segments (batch rows)
  torch::Tensor map_features;  // float [E, 7]
  std::vector<int64_t> map_begin;  // per example, then M: its first segment

  // Decoder tokens: N over the batch.
  torch::Tensor kind;                           // int64 [N]: TokenKind
  torch::Tensor light_state, light_slot, map_id, intra, agent_slot, agent_type, motion_action;  // int64 [N]
  torch::Tensor motion_state;                   // float [N, 5]
  torch::Tensor relative_state;                 // float [N, 8]
  std::vector<int64_t> token_begin;             // per example, then N
  SparseKeys self_keys;                         // token -> tokens (batch rows)
  torch::Tensor self_features;                  // float [Es, 7]
  SparseKeys cross_keys;                        // posed token -> segments (batch rows); none for the others
  torch::Tensor cross_features;                 // float [Ec, 7]
  std::vector<torch::Tensor> unposed;           // per example: int64 rows of its tokens without a position

  // Rows reading each head and their targets (only valid targets are listed).
  torch::Tensor light_rows, light_target;       // int64
  torch::Tensor motion_rows, motion_target;
  torch::Tensor type_rows, type_target;
  torch::Tensor end_rows, end_target;
  torch::Tensor end_first;                      // bool, per end target: at its sequence's first step (the scene's
                                                // placement; later steps ask only whether a new agent enters)
  std::vector<torch::Tensor> segment_rows, segment_target;  // per example (target: index in its own map)
  torch::Tensor state_rows, state_target;       // MS rows; [rows, 8]

  int64_t tokens() const { return kind.size(0); }
  int64_t target_count() const;  // targets over every head (a relative state counts 8)
};

Batch make_batch(const std::vector<const TeacherForcedExample*>& examples);

}  // namespace ss::train
