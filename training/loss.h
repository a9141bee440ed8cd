// The training loss: cross-entropy per head on valid targets only, summed over the heads of the stage (the paper's
// two stages: motion and lights first, then every head), with losses and accuracies per head for the logs.
#pragma once

#include <map>
#include <string>

#include <torch/torch.h>

#include "training/batch.h"
#include "training/model.h"

namespace ss::train {

enum class Stage { motion_and_lights = 1, all_heads = 2 };

struct HeadStat {
  double loss = 0;     // mean cross-entropy
  int64_t count = 0;   // targets
  double accuracy = 0; // share of targets that are the arg max
};

struct Loss {
  torch::Tensor total;                    // what backward() runs on
  std::map<std::string, HeadStat> heads;  // light, motion, type, segment, state, end, end0 (end at the first step)
};

// The heads a stage trains.
bool stage_trains(Stage s, const std::string& head);

// scene_end_weight: the weight of the end-of-agents targets at a sequence's first step in the end head's mean (the
// others weigh 1). The "end0" stat is those targets alone, for the logs (not in the total).
// placement_weight: the weight of the placement heads (type, map-segment pointer, relative state) in the total; the
// others weigh 1. The heads' stats are unweighted.
Loss compute_loss(const HeadLogits& logits, const Batch& b, Stage stage, double scene_end_weight = 1.0,
                  double placement_weight = 1.0);

}  // namespace ss::train
