// A training run: options, the loop (teacher forcing, two stages, AdamW with warm-up and cosine decay, gradient
// clipping), validation, checkpoints that resume exactly, and export to the engine's weight file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace ss::train {

struct TrainOptions {
  std::string config = "small";         // small | large
  std::vector<std::string> real_data;   // real WOMD scenarios (train split only)
  std::vector<std::string> synthetic_data;  // SUMO-generated scenarios
  std::vector<std::string> val_data;    // never trained on
  std::string out;                      // run directory: checkpoint, logs, exported weights
  bool resume = false;
  double real_fraction = 0.7;           // share of samples drawn from the real data
  int64_t steps = 20000;                // optimizer steps
  int64_t stage1_steps = 4000;          // motion and light heads only, then every head
  int batch = 4;                        // scenarios per optimizer step
  double lr = 5e-4;
  double min_lr_ratio = 0.05;           // cosine decays to lr * this
  int64_t warmup = 500;
  double weight_decay = 0.01;
  double clip = 1.0;
  int max_agents = 32;                  // per sample
  int max_map_segments = 1500;          // per sample
  uint64_t seed = 1;
  int threads = 2;
  int64_t log_every = 10;
  int64_t val_every = 500;
  int val_scenarios = 16;
  int64_t checkpoint_every = 100;
  int64_t eval_every = 0;               // 0: no periodic `scenestreamer eval`
  std::string eval_tool;                // the scenestreamer binary for the periodic eval
  int eval_scenarios = 8;
  int64_t stop_after = 0;               // stop (with a checkpoint) after this many steps in this process; 0: no limit
  std::string init_from;                // a fresh run (step 0, new optimizer) starting from this checkpoint's weights
  int catk_top_k = 0;                   // > 0: CAT-K closed-loop fine-tuning (closed_loop_example) with this K
  double scene_end_weight = 1.0;        // weight of the end-of-agents targets at a sequence's first step (loss.h)
  double placement_weight = 1.0;        // weight of the type, pointer and relative-state heads in the loss (loss.h)
};

absl::Status run_training(const TrainOptions& options);
// The OpenBLAS kernel family this CPU runs: SkylakeX with AVX-512, Haswell with AVX2, else Prescott.
const char* openblas_coretype();
// Writes the checkpoint's model as an engine weight file.
absl::Status export_checkpoint(const std::string& checkpoint, const std::string& out);

}  // namespace ss::train
