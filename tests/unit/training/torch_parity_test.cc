// The torch model (training/) and the engine's model compute the same function: random weights made in torch,
// exported, loaded by the engine, and both run on the same teacher-forced real scenario. Every head is compared.
#include <gtest/gtest.h>

#include "engine/model/model.h"
#include "engine/scenario/read.h"
#include "training/teacher_forcing.h"
#include "training/batch.h"
#include "training/incremental.h"
#include "training/model.h"

namespace ss::train {
namespace {

// A tiny configuration (fast) that still has several heads, layers and blocks.
ModelConfig tiny_config() {
  ModelConfig c;
  c.name = "tiny";
  c.d_model = 32;
  c.heads = 4;
  c.encoder_layers = 1;
  c.decoder_layers = 2;
  c.relation_dim = 8;
  c.polyline_dim = 16;
  c.rs_layers = 1;
  c.max_map_segments = 400;
  return c;
}

// Every parameter random (biases, norms and AdaLN too, which init_weights leaves at 0 or 1).
TorchModel random_model(const ModelConfig& c) {
  TorchModel m(init_weights(c, 7));
  torch::manual_seed(3);
  torch::NoGradGuard no_grad;
  for (const auto& [name, t] : m.named_parameters()) const_cast<torch::Tensor&>(t).copy_(torch::randn_like(t) * 0.2);
  return m;
}

Scenario real_scenario() {
  auto s = read_scenarios(std::string(SS_DATA_DIR) + "/womd/tfrecord/motion_data_one_scenario.tfrecord");
  EXPECT_TRUE(s.ok()) << s.status();
  return std::move((*s)[0]);
}

// Prints each comparison's largest difference (docs/training.md quotes them).
float report(const char* what, float d) {
  std::printf("  max |engine - torch| %-28s %.2e\n", what, d);
  return d;
}

float max_diff(const Mat& engine, const torch::Tensor& t) {
  const torch::Tensor c = t.detach().contiguous();
  EXPECT_EQ(engine.rows(), c.size(0));
  EXPECT_EQ(engine.cols(), c.numel() / std::max<int64_t>(1, c.size(0)));
  float d = 0;
  const float* p = c.data_ptr<float>();
  for (int64_t i = 0; i < engine.size(); ++i) d = std::max(d, std::abs(engine.data()[i] - p[i]));
  return d;
}

Mat rows_of(const Mat& m, const torch::Tensor& rows) {
  std::vector<int> r;
  for (int64_t i = 0; i < rows.numel(); ++i) r.push_back(static_cast<int>(rows[i].item<int64_t>()));
  return m(r, Eigen::all);
}

TEST(Parity, TorchAndEngineAgreeOnEveryHead) {
  const ModelConfig config = tiny_config();
  const TorchModel torch_model = random_model(config);
  ModelOptions fp32;  // the 1e-4 bound is fp32's: fp16 keys and bf16 products have their own (precision_test)
  fp32.kv_precision = KvPrecision::fp32;
  fp32.matmul_precision = MatmulPrecision::fp32;
  auto engine_model = Model::create(torch_model.to_weights(), fp32);
  ASSERT_TRUE(engine_model.ok()) << engine_model.status();

  TeacherForcingOptions opts;
  opts.max_agents = 12;
  opts.slot_seed = 5;
  auto ex = teacher_forced_example(real_scenario(), config, opts);
  ASSERT_TRUE(ex.ok()) << ex.status();
  ASSERT_GT(ex->light_target.size(), 0u);
  const Batch b = make_batch({&*ex});
  ASSERT_GT(b.light_rows.numel(), 0);
  ASSERT_GT(b.segment_rows[0].numel(), 0);

  torch::NoGradGuard no_grad;
  const Forward f = torch_model.forward(b);
  const HeadLogits heads = torch_model.heads(b, f);

  auto map = (*engine_model)->encode_map(ex->segments);
  ASSERT_TRUE(map.ok()) << map.status();
  const float tol = 1e-4f;
  EXPECT_LT(report("map tokens", max_diff((*map)->tokens, f.map_tokens)), tol);
  std::vector<DecoderToken> tokens = ex->tokens;
  const Mat h = (*engine_model)->decode_full(**map, tokens);
  EXPECT_LT(report("decoder outputs", max_diff(h, f.hidden)), tol);

  const Model& m = **engine_model;
  EXPECT_LT(report("light head", max_diff(m.light_logits(rows_of(h, b.light_rows)), heads.light)), tol);
  EXPECT_LT(report("motion head", max_diff(m.motion_logits(rows_of(h, b.motion_rows)), heads.motion)), tol);
  EXPECT_LT(report("agent type head", max_diff(m.agent_type_logits(rows_of(h, b.type_rows)), heads.type)), tol);
  EXPECT_LT(report("end-of-agents head", max_diff(m.end_of_agents_logits(rows_of(h, b.end_rows)), heads.end)), tol);
  EXPECT_LT(report("map-segment pointer head",
                   max_diff(m.map_segment_logits(rows_of(h, b.segment_rows[0]), **map), heads.segment[0])),
            tol);
  // The relative-state head, field by field with the target's earlier fields as the prefix (as a session samples).
  const Mat z = rows_of(h, b.state_rows);
  ASSERT_GT(z.rows(), 0);
  float state_diff = 0;
  for (int r = 0; r < z.rows(); ++r) {
    std::vector<int> prefix;
    for (int field = 0; field < kRsFields; ++field) {
      const Vec logits = m.relative_state_logits(z.row(r), prefix);
      const torch::Tensor t = heads.state[r][field];
      for (int c = 0; c < kRsBins; ++c) state_diff = std::max(state_diff, std::abs(logits[c] - t[c].item<float>()));
      prefix.push_back(static_cast<int>(b.state_target[r][field].item<int64_t>()));
    }
  }
  EXPECT_LT(report("relative-state head", state_diff), tol);
}

}  // namespace
}  // namespace ss::train

namespace ss::train {
namespace {

// The torch model stepped over its own cache (the benchmark's comparison) gives the full forward's outputs.
TEST(Parity, TorchIncrementalMatchesTorchFull) {
  const ModelConfig config = tiny_config();
  const TorchModel model = random_model(config);
  TeacherForcingOptions opts;
  opts.max_agents = 10;
  auto ex = teacher_forced_example(real_scenario(), config, opts);
  ASSERT_TRUE(ex.ok()) << ex.status();
  const Batch b = make_batch({&*ex});
  torch::NoGradGuard no_grad;
  const torch::Tensor full = model.forward(b).hidden;
  TorchDecoder decoder(model, ex->segments);
  std::vector<torch::Tensor> parts;
  for (size_t i = 0; i < ex->tokens.size();) {  // one call per step, as a session decodes (window eviction included)
    size_t j = i;
    while (j < ex->tokens.size() && ex->tokens[j].step == ex->tokens[i].step) ++j;
    std::vector<DecoderToken> step(ex->tokens.begin() + i, ex->tokens.begin() + j);
    parts.push_back(decoder.decode(step));
    i = j;
  }
  EXPECT_LT((torch::cat(parts) - full).abs().max().item<float>(), 1e-4);
  EXPECT_LT(decoder.cached_tokens(), static_cast<int>(ex->tokens.size())) << "old steps were evicted";
}

}  // namespace
}  // namespace ss::train
