// scenestreamer-train: trains SceneStreamer in libtorch and exports the engine's weight file.
//   scenestreamer-train --config small|large --data DIR... --out DIR [--resume] [options]
//   scenestreamer-train export --checkpoint DIR/checkpoint.pt --out model.safetensors   (export_command.cc)
//   scenestreamer-train plot --run DIR --out curves.svg                                  (plot_command.cc)
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "absl/flags/flag.h"
#include "absl/strings/str_split.h"
#include "common/command_line.h"
#include "training/commands.h"
#include "training/trainer.h"

namespace {
const ss::train::TrainOptions kDefaults;
}  // namespace

ABSL_FLAG(std::string, config, kDefaults.config, "model configuration: small or large");
ABSL_FLAG(std::string, data, "", "real WOMD scenarios to train on (TFRecord or JSON files or directories, comma-separated)");
ABSL_FLAG(std::string, synthetic, "", "SUMO-generated scenarios (`scenestreamer dataset sumo`), comma-separated");
ABSL_FLAG(std::string, val, "", "validation scenarios, comma-separated (never trained on; a scenario id in both is an error)");
ABSL_FLAG(std::string, out, "", "the run directory (required)");
ABSL_FLAG(bool, resume, false, "continue the run in --out from its checkpoint");
ABSL_FLAG(double, real_fraction, kDefaults.real_fraction, "share of samples drawn from --data");
ABSL_FLAG(int64_t, steps, kDefaults.steps, "optimizer steps");
ABSL_FLAG(int64_t, stage1_steps, kDefaults.stage1_steps, "steps training the motion and light heads only");
ABSL_FLAG(int, batch, kDefaults.batch, "scenarios per optimizer step");
ABSL_FLAG(double, lr, kDefaults.lr, "peak learning rate (cosine decay after the warm-up)");
ABSL_FLAG(int64_t, warmup, kDefaults.warmup, "warm-up steps");
ABSL_FLAG(double, weight_decay, kDefaults.weight_decay, "AdamW weight decay");
ABSL_FLAG(double, clip, kDefaults.clip, "gradient norm clip");
ABSL_FLAG(int, max_agents, kDefaults.max_agents, "agents per sample");
ABSL_FLAG(int, max_map_segments, kDefaults.max_map_segments, "map segments per sample");
ABSL_FLAG(uint64_t, seed, kDefaults.seed, "random seed");
ABSL_FLAG(int, threads, kDefaults.threads, "torch threads");
ABSL_FLAG(int64_t, log_every, kDefaults.log_every, "steps between train_log.csv rows");
ABSL_FLAG(int64_t, val_every, kDefaults.val_every, "steps between validations");
ABSL_FLAG(int, val_scenarios, kDefaults.val_scenarios, "scenarios of each validation");
ABSL_FLAG(int64_t, checkpoint_every, kDefaults.checkpoint_every, "steps between checkpoints (also every 5 minutes)");
ABSL_FLAG(int64_t, eval_every, kDefaults.eval_every, "steps between short `scenestreamer eval` runs of the val data; 0: none");
ABSL_FLAG(std::string, eval_tool, "", "the scenestreamer binary those evals run");
ABSL_FLAG(int, eval_scenarios, kDefaults.eval_scenarios, "val scenarios of each eval");
ABSL_FLAG(int64_t, stop_after, kDefaults.stop_after,
          "stop after N steps in this process, with a checkpoint (--resume continues); 0: no limit");

ABSL_FLAG(std::string, init_from, "",
          "start a fresh run (step 0, new optimizer and schedule) from this checkpoint's weights, e.g. to fine-tune");
ABSL_FLAG(double, scene_end_weight, kDefaults.scene_end_weight,
          "weight of the end-of-agents targets at a sequence's first step, where the scene is placed (the others "
          "weigh 1): they are the only ones that ask how full a scene is");
ABSL_FLAG(double, placement_weight, kDefaults.placement_weight,
          "weight of the placement heads (agent type, map-segment pointer, relative state) in the loss (the others "
          "weigh 1): a fine-tune of how scenes are placed");
ABSL_FLAG(int, catk, kDefaults.catk_top_k,
          "CAT-K closed-loop fine-tuning: roll each sample out with the current model, moving each agent by the one of "
          "its K most probable tokens nearest the log, and train toward the log from there; 0: teacher forcing");

namespace {

constexpr const char* kUsage =
    "usage: scenestreamer-train --config small|large --data PATH[,PATH...] --out DIR [--resume] [flags]\n"
    "       scenestreamer-train export --checkpoint DIR/checkpoint.pt --out model.safetensors\n"
    "       scenestreamer-train plot --run DIR --out curves.svg   (loss curves per head from the run's logs)\n"
    "  The run directory holds checkpoint.pt (model, optimizer, schedule, data position), latest.safetensors,\n"
    "  train_log.csv and val_log.csv. SIGINT or SIGTERM stops after the current step with a checkpoint.\n"
    "  `scenestreamer-train export --help` and `plot --help` show those commands' flags.\n";

std::vector<std::string> paths(const std::string& s) {
  std::vector<std::string> out;
  for (auto p : absl::StrSplit(s, ',', absl::SkipEmpty())) out.emplace_back(p);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  // OpenBLAS reads OPENBLAS_CORETYPE when it loads: without it, it does not recognise these EPYC CPUs and picks
  // slow kernels. Name the kernels the CPU can run (SkylakeX needs AVX-512) and start again, before any work.
  if (!std::getenv("OPENBLAS_CORETYPE")) {
    setenv("OPENBLAS_CORETYPE", ss::train::openblas_coretype(), 1);
    execv("/proc/self/exe", argv);
  }
  if (argc > 1 && std::string(argv[1]) == "export") return ss::train::export_main(argc - 1, argv + 1);
  if (argc > 1 && std::string(argv[1]) == "plot") return ss::train::plot_main(argc - 1, argv + 1);
  const ss::cli::Command command{"scenestreamer-train", kUsage, __FILE__, {}};
  ss::cli::CommandLine line;
  if (auto exit_code = ss::cli::parse_command(command, argc, argv, &line)) return *exit_code;
  ss::train::TrainOptions o;
  o.config = absl::GetFlag(FLAGS_config);
  o.real_data = paths(absl::GetFlag(FLAGS_data));
  o.synthetic_data = paths(absl::GetFlag(FLAGS_synthetic));
  o.val_data = paths(absl::GetFlag(FLAGS_val));
  o.out = absl::GetFlag(FLAGS_out);
  o.resume = absl::GetFlag(FLAGS_resume);
  o.real_fraction = absl::GetFlag(FLAGS_real_fraction);
  o.steps = absl::GetFlag(FLAGS_steps);
  o.stage1_steps = absl::GetFlag(FLAGS_stage1_steps);
  o.batch = absl::GetFlag(FLAGS_batch);
  o.lr = absl::GetFlag(FLAGS_lr);
  o.warmup = absl::GetFlag(FLAGS_warmup);
  o.weight_decay = absl::GetFlag(FLAGS_weight_decay);
  o.clip = absl::GetFlag(FLAGS_clip);
  o.max_agents = absl::GetFlag(FLAGS_max_agents);
  o.max_map_segments = absl::GetFlag(FLAGS_max_map_segments);
  o.seed = absl::GetFlag(FLAGS_seed);
  o.threads = absl::GetFlag(FLAGS_threads);
  o.log_every = absl::GetFlag(FLAGS_log_every);
  o.val_every = absl::GetFlag(FLAGS_val_every);
  o.val_scenarios = absl::GetFlag(FLAGS_val_scenarios);
  o.checkpoint_every = absl::GetFlag(FLAGS_checkpoint_every);
  o.eval_every = absl::GetFlag(FLAGS_eval_every);
  o.eval_tool = absl::GetFlag(FLAGS_eval_tool);
  o.eval_scenarios = absl::GetFlag(FLAGS_eval_scenarios);
  o.stop_after = absl::GetFlag(FLAGS_stop_after);
  o.init_from = absl::GetFlag(FLAGS_init_from);
  o.catk_top_k = absl::GetFlag(FLAGS_catk);
  o.scene_end_weight = absl::GetFlag(FLAGS_scene_end_weight);
  o.placement_weight = absl::GetFlag(FLAGS_placement_weight);
  if (auto s = ss::train::run_training(o); !s.ok()) {
    std::fprintf(stderr, "scenestreamer-train: %s\n", std::string(s.message()).c_str());
    return 1;
  }
  return 0;
}
