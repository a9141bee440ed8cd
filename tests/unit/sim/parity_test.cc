// The incremental path (new tokens only, over the KV cache) against a full recompute of the whole history, with fp32
// keys and values (the fp16 default's parity is in precision_test).
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "tests/unit/sim/session_fixture.h"

namespace ss {
namespace {

TEST(Parity, IncrementalMatchesFullRecomputeOver19Steps) {
  testing::World w = testing::load_world("small", 1, testing::kv(KvPrecision::fp32));
  SessionOptions o;
  o.mode = SessionMode::full;  // agents enter when the model says so
  o.seed = 11;
  o.roi_radius = 40;           // and leave soon: random weights drive them about
  o.max_agents = 24;
  Session::Probe probe;
  auto s = Session::create(w.model, w.scenario, w.map, o, &probe);
  ASSERT_TRUE(s.ok()) << s.status();
  std::set<int64_t> entered, left;
  for (int step = 3; step < 19; ++step) {
    auto r = (*s)->step({testing::sdc_control(w, step)});
    ASSERT_TRUE(r.ok()) << r.status();
    for (const AgentView& a : r->agents)
      if (a.entered) entered.insert(a.id);
    left.insert(r->left.begin(), r->left.end());
  }
  EXPECT_EQ((*s)->step_index(), 18);
  EXPECT_GT(entered.size(), 3u) << "the rollout should have agents entering";
  EXPECT_GT(left.size(), 1u) << "the rollout should have agents leaving";

  std::vector<DecoderToken> all;
  for (const auto& b : probe.batches) all.insert(all.end(), b.begin(), b.end());
  const Mat full = w.model->decode_full(*w.map, all);
  ASSERT_EQ(full.rows(), static_cast<Eigen::Index>(all.size()));

  double max_hidden = 0, max_logit = 0;
  size_t row = 0, motion_tokens = 0, light_tokens = 0;
  for (size_t b = 0; b < probe.batches.size(); ++b) {
    const Mat& inc = probe.outputs[b];
    const Mat ref = full.middleRows(row, inc.rows());
    max_hidden = std::max<double>(max_hidden, (inc - ref).cwiseAbs().maxCoeff());
    for (int i = 0; i < inc.rows(); ++i) {
      const TokenKind kind = probe.batches[b][i].kind;
      Mat a, c;
      if (kind == TokenKind::motion) a = w.model->motion_logits(inc.row(i)), c = w.model->motion_logits(ref.row(i)), ++motion_tokens;
      if (kind == TokenKind::light) a = w.model->light_logits(inc.row(i)), c = w.model->light_logits(ref.row(i)), ++light_tokens;
      if (kind == TokenKind::soa) a = w.model->agent_type_logits(inc.row(i)), c = w.model->agent_type_logits(ref.row(i));
      if (kind == TokenKind::type) a = w.model->map_segment_logits(inc.row(i), *w.map), c = w.model->map_segment_logits(ref.row(i), *w.map);
      if (a.size()) max_logit = std::max<double>(max_logit, (a - c).cwiseAbs().maxCoeff());
    }
    row += inc.rows();
  }
  EXPECT_GT(motion_tokens, 60u);  // 87 at this seed
  EXPECT_GT(light_tokens, 100u);
  EXPECT_LT(max_hidden, 1e-4);
  EXPECT_LT(max_logit, 1e-4);
  std::printf("parity over %zu tokens in %zu batches: max |hidden diff| %.3g, max |logit diff| %.3g\n", all.size(),
              probe.batches.size(), max_hidden, max_logit);
}

}  // namespace
}  // namespace ss

namespace ss {
namespace {

Scenario shifted(Scenario s, double dx, double dy) {
  for (Track& t : s.tracks)
    for (ObjectState& st : t.states)
      if (st.valid) st.x += dx, st.y += dy;
  for (MapFeature& f : s.map_features)
    for (MapPoint& p : f.points) p.x += dx, p.y += dy;
  for (auto& frame : s.signals)
    for (SignalLaneState& l : frame) l.stop_point.x += dx, l.stop_point.y += dy;
  return s;
}

// Asking for some outputs only (the others skip their last layer's self-attention and feed-forward) gives the same
// rows as asking for all, and the same cache. Large configuration: its kernels take the 32-wide head path.
TEST(Parity, OutputSubsetMatchesAllOutputs) {
  testing::World w = testing::load_world("large", 1, testing::kv(KvPrecision::fp32));
  SessionOptions o;
  o.seed = 5;
  Session::Probe probe;
  auto s = Session::create(w.model, w.scenario, w.map, o, &probe);
  ASSERT_TRUE(s.ok()) << s.status();
  for (int step = 3; step < 6; ++step) ASSERT_TRUE((*s)->step({testing::sdc_control(w, step)}).ok());
  KvCache all_cache = w.model->new_cache(), some_cache = w.model->new_cache();
  size_t checked = 0;
  for (const auto& batch : probe.batches) {
    std::vector<DecoderToken> a = batch, b = batch;
    std::vector<int> some;
    for (int i = static_cast<int>(batch.size()) - 1; i >= 0; i -= 3) some.push_back(i);  // descending, a gap of 2
    const Mat all = w.model->decode(*w.map, all_cache, a);
    const Mat part = w.model->decode(*w.map, some_cache, b, some);
    ASSERT_EQ(part.rows(), static_cast<Eigen::Index>(some.size()));
    for (size_t r = 0; r < some.size(); ++r, ++checked)
      EXPECT_LT((part.row(r) - all.row(some[r])).cwiseAbs().maxCoeff(), 1e-5) << "token " << some[r];
  }
  EXPECT_GT(checked, 100u);
  ASSERT_EQ(all_cache.size(), some_cache.size());
  const int d = all_cache.d_model;
  for (size_t l = 0; l < all_cache.k.size(); ++l)
    for (int j = 0; j < all_cache.size(); ++j) {
      ASSERT_TRUE(std::equal(all_cache.key_row(l, j), all_cache.key_row(l, j) + d, some_cache.key_row(l, j)))
          << "layer " << l << " token " << j;
      ASSERT_TRUE(std::equal(all_cache.value_row(l, j), all_cache.value_row(l, j) + d, some_cache.value_row(l, j)))
          << "layer " << l << " token " << j;
    }
}

TEST(Parity, DecoderIsTranslationInvariant) {
  testing::World w = testing::load_world("small", 1, testing::kv(KvPrecision::fp32));
  testing::World moved = w;
  moved.scenario = std::make_shared<const Scenario>(shifted(*w.scenario, 1234.5, -2345.25));
  moved.map = *w.model->encode_map(nearest_segments(segment_map(*moved.scenario), scenario_focus(*moved.scenario)));
  EXPECT_LT((w.map->tokens - moved.map->tokens).cwiseAbs().maxCoeff(), 1e-4);
  SessionOptions o;
  Session::Probe a, b;
  ASSERT_TRUE(Session::create(w.model, w.scenario, w.map, o, &a).ok());
  ASSERT_TRUE(Session::create(moved.model, moved.scenario, moved.map, o, &b).ok());
  ASSERT_EQ(a.outputs.size(), b.outputs.size());
  double max_diff = 0;
  for (size_t i = 0; i < a.outputs.size(); ++i)
    max_diff = std::max<double>(max_diff, (a.outputs[i] - b.outputs[i]).cwiseAbs().maxCoeff());
  EXPECT_LT(max_diff, 1e-4);
}

}  // namespace
}  // namespace ss
