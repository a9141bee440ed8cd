// Training runs: the loss falls on a few real scenarios, and a run stopped and resumed from its checkpoint ends with
// the same weights, byte for byte, as one that ran straight through; so does a CAT-K fine-tuning run started from
// another run's weights.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "engine/scenario/read.h"
#include "training/teacher_forcing.h"
#include "tests/unit/training/training_fixture.h"
#include "training/batch.h"
#include "training/loss.h"
#include "training/model.h"
#include "training/trainer.h"

namespace ss::train {
namespace {

namespace fs = std::filesystem;

const std::string kVal = std::string(SS_DATA_DIR) + "/womd/json/val";

std::vector<std::string> val_files(int n) {
  auto files = list_scenario_files(kVal, false);
  EXPECT_TRUE(files.ok()) << files.status();
  files->resize(std::min<size_t>(files->size(), n));
  return *files;
}

TEST(TrainRun, LossFallsOnAFewRealScenarios) {
  const ModelConfig c = testing::tiny_config(2);
  torch::manual_seed(1);
  TorchModel model(init_weights(c, 1));
  // The real TFRecord has lights; the JSON file adds a second map.
  std::vector<TeacherForcedExample> examples(2);
  ASSERT_NO_FATAL_FAILURE(testing::small_example(testing::kRealTfRecord, c, &examples[0]));
  ASSERT_NO_FATAL_FAILURE(testing::small_example(val_files(1)[0], c, &examples[1]));
  const Batch b = make_batch({&examples[0], &examples[1]});
  torch::optim::AdamW opt(model.parameters(), torch::optim::AdamWOptions(3e-3));
  double first = 0, last = 0;
  for (int step = 0; step < 30; ++step) {
    opt.zero_grad();
    const Loss loss = compute_loss(model.heads(b, model.forward(b)), b, Stage::all_heads);
    loss.total.backward();
    opt.step();
    (step == 0 ? first : last) = loss.total.item<double>();
    for (const auto& [name, h] : loss.heads) EXPECT_GT(h.count, 0) << name << " has no targets";
  }
  EXPECT_LT(last, 0.6 * first) << "loss " << first << " -> " << last;
}

std::string file_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// A short run on two real val files: small samples, no validation.
TrainOptions short_run() {
  TrainOptions o;
  o.config = "small";
  o.real_data = val_files(2);
  o.max_agents = 4;
  o.max_map_segments = 200;
  o.val_every = 0;
  return o;
}

TEST(TrainRun, ResumedRunEndsWithTheSameWeights) {
  const fs::path dir = fs::temp_directory_path() / ("ss_train_resume_" + std::to_string(getpid()));
  fs::remove_all(dir);
  TrainOptions o = short_run();
  o.steps = 4;
  o.stage1_steps = 2;  // the resumed half crosses into the second stage
  o.warmup = 2;
  o.batch = 1;
  o.log_every = 1;
  o.out = (dir / "straight").string();
  ASSERT_TRUE(run_training(o).ok());
  o.out = (dir / "resumed").string();
  o.stop_after = 2;
  ASSERT_TRUE(run_training(o).ok());
  const std::string half = file_bytes(dir / "resumed" / "latest.safetensors");
  o.resume = true;
  o.stop_after = 0;
  ASSERT_TRUE(run_training(o).ok());
  const std::string straight = file_bytes(dir / "straight" / "latest.safetensors");
  EXPECT_FALSE(straight.empty());
  EXPECT_NE(half, straight) << "the first half alone should not reach the end's weights";
  EXPECT_EQ(file_bytes(dir / "resumed" / "latest.safetensors"), straight);
  // Without --resume an existing run is not overwritten.
  o.resume = false;
  EXPECT_FALSE(run_training(o).ok());
  fs::remove_all(dir);
}

TEST(TrainRun, ClosedLoopFineTuningFromAnotherRunResumesExactly) {
  const fs::path dir = fs::temp_directory_path() / ("ss_train_catk_" + std::to_string(getpid()));
  fs::remove_all(dir);
  TrainOptions o = short_run();
  o.steps = 2;
  o.stage1_steps = 0;
  o.warmup = 1;
  o.batch = 2;
  o.out = (dir / "base").string();
  ASSERT_TRUE(run_training(o).ok());
  o.init_from = (dir / "base" / "checkpoint.pt").string();
  o.catk_top_k = 4;
  o.steps = 4;
  o.threads = 2;  // two samples rolled out at once
  o.out = (dir / "straight").string();
  ASSERT_TRUE(run_training(o).ok());
  o.out = (dir / "resumed").string();
  o.stop_after = 2;
  ASSERT_TRUE(run_training(o).ok());
  o.resume = true;
  o.stop_after = 0;
  ASSERT_TRUE(run_training(o).ok());
  const std::string straight = file_bytes(dir / "straight" / "latest.safetensors");
  EXPECT_FALSE(straight.empty());
  EXPECT_NE(file_bytes(dir / "base" / "latest.safetensors"), straight) << "fine-tuning changed the weights";
  EXPECT_EQ(file_bytes(dir / "resumed" / "latest.safetensors"), straight);
  // The starting weights are a checkpoint of the same configuration.
  o.out = (dir / "other").string();
  o.resume = false;
  o.init_from = (dir / "base" / "latest.safetensors").string();
  EXPECT_FALSE(run_training(o).ok()) << "a weight file is not a checkpoint";
  o.catk_top_k = -1;
  o.init_from.clear();
  EXPECT_FALSE(run_training(o).ok()) << "--catk must not be negative";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ss::train
