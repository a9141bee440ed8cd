// The training loss's end-of-agents term: its targets at a sequence's first step (the scene's placement) reported
// alone as "end0", and weighted by scene_end_weight in the end head's mean; placement_weight scales the placement
// heads' terms.
#include <gtest/gtest.h>

#include "tests/unit/training/training_fixture.h"
#include "training/batch.h"
#include "training/loss.h"
#include "training/model.h"

namespace ss::train {
namespace {

// A tiny model's head logits on one real example.
class LossTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const ModelConfig c = testing::tiny_config(1);
    torch::manual_seed(1);
    TorchModel model(init_weights(c, 1));
    ASSERT_NO_FATAL_FAILURE(testing::small_example(testing::kRealTfRecord, c, &ex));
    b = make_batch({&ex});
    torch::NoGradGuard no_grad;
    logits = model.heads(b, model.forward(b));
  }
  TeacherForcedExample ex;
  Batch b;
  HeadLogits logits;
};

TEST_F(LossTest, SceneEndTargetsAreReportedAloneAndWeighted) {
  int first = 0, all = 0;
  for (size_t i = 0; i < ex.tokens.size(); ++i) {
    if (ex.end_target[i] == kNoTarget) continue;
    ++all;
    first += ex.tokens[i].step == 0;
  }
  ASSERT_GT(first, 1);
  ASSERT_GT(all, first);

  torch::NoGradGuard no_grad;
  const Loss plain = compute_loss(logits, b, Stage::all_heads);
  EXPECT_EQ(plain.heads.at("end").count, all);
  EXPECT_EQ(plain.heads.at("end0").count, first);
  // Weighting changes the total by the end term alone, and only in how the two kinds of target are averaged.
  const double w = 5;
  const Loss weighted = compute_loss(logits, b, Stage::all_heads, w);
  const double sum_first = plain.heads.at("end0").loss * first;
  const double sum_all = plain.heads.at("end").loss * all;
  const double expected = (sum_all - sum_first + w * sum_first) / (all - first + w * first);
  EXPECT_NEAR(weighted.total.item<double>() - plain.total.item<double>(), expected - plain.heads.at("end").loss, 1e-5);
  EXPECT_NE(plain.heads.at("end0").loss, plain.heads.at("end").loss);
  // The reported stats stay unweighted.
  EXPECT_DOUBLE_EQ(weighted.heads.at("end").loss, plain.heads.at("end").loss);
}

TEST_F(LossTest, PlacementWeightScalesTheTypePointerAndStateHeadsAlone) {
  torch::NoGradGuard no_grad;
  const Loss plain = compute_loss(logits, b, Stage::all_heads);
  const double w = 3;
  const Loss weighted = compute_loss(logits, b, Stage::all_heads, 1.0, w);
  double placement = 0;
  for (const char* head : {"type", "segment", "state"}) {
    ASSERT_GT(plain.heads.at(head).count, 0) << head;
    placement += plain.heads.at(head).loss;
    EXPECT_DOUBLE_EQ(weighted.heads.at(head).loss, plain.heads.at(head).loss) << head;  // stats unweighted
  }
  EXPECT_NEAR(weighted.total.item<double>() - plain.total.item<double>(), (w - 1) * placement, 1e-4);
  // Stage 1 trains none of them: the weight changes nothing there.
  EXPECT_NEAR(compute_loss(logits, b, Stage::motion_and_lights, 1.0, w).total.item<double>(),
              compute_loss(logits, b, Stage::motion_and_lights).total.item<double>(), 1e-6);
}

}  // namespace
}  // namespace ss::train
