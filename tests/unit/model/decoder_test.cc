// The decoder's kept rows of position-less tokens (KvCache::poseless): computed one token at a time, so they do not
// depend on how tokens were batched, and kept while the last two steps read them.
#include <gtest/gtest.h>

#include <cstring>

#include "tests/unit/sim/session_fixture.h"

namespace ss {
namespace {

struct Rollout {
  testing::World w;
  Session::Probe probe;
};

Rollout roll(const std::string& config) {
  Rollout r{testing::load_world(config), {}};
  SessionOptions o;
  o.mode = SessionMode::full;
  o.seed = 5;  // 34 kept rows (seed 3 made 8 once the softmax left its weights unnormalised)
  o.max_agents = 24;
  o.temperature = 1.0;  // random weights: unsharpened sampling makes agents (SOA, TYPE rows) in these steps
  auto s = Session::create(r.w.model, r.w.scenario, r.w.map, o, &r.probe);
  EXPECT_TRUE(s.ok()) << s.status();
  for (int step = 3; step < 9; ++step) EXPECT_TRUE((*s)->step({testing::sdc_control(r.w, step)}).ok());
  return r;
}

bool same_bits(const Vec& a, const Vec& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(Decoder, KeptPoselessRowsDoNotDependOnTheBatch) {
  const Rollout r = roll("small");
  const Model& m = *r.w.model;
  // The same tokens decoded batch by batch, and each batch split in two at an odd place.
  KvCache whole = m.new_cache(), split = m.new_cache();
  for (const auto& batch : r.probe.batches) {
    std::vector<DecoderToken> a = batch;
    m.decode(*r.w.map, whole, a);
    const size_t cut = batch.size() / 3 + 1;
    std::vector<DecoderToken> b1(batch.begin(), batch.begin() + std::min(cut, batch.size()));
    std::vector<DecoderToken> b2(batch.begin() + std::min(cut, batch.size()), batch.end());
    m.decode(*r.w.map, split, b1);
    if (!b2.empty()) m.decode(*r.w.map, split, b2);
  }
  ASSERT_GT(whole.poseless.size(), 10u) << "the rollout should have agents (SOA, TYPE) and SOS/EOS";
  EXPECT_EQ(whole.poseless.size(), split.poseless.size());
  for (const auto& [key, e] : whole.poseless) {
    auto it = split.poseless.find(key);
    ASSERT_NE(it, split.poseless.end());
    EXPECT_TRUE(same_bits(e.x, it->second.x));
  }
  // A cache that starts from the last batches only (as a restored session replays its saved batches) computes the
  // same kept rows.
  KvCache late = m.new_cache();
  const auto& batches = r.probe.batches;
  for (size_t b = batches.size() - 3; b < batches.size(); ++b) {
    std::vector<DecoderToken> t = batches[b];
    m.decode(*r.w.map, late, t);
  }
  for (const auto& [key, e] : late.poseless) {
    auto it = whole.poseless.find(key);
    ASSERT_NE(it, whole.poseless.end());
    EXPECT_TRUE(same_bits(e.x, it->second.x));
  }
}

TEST(Decoder, KeptPoselessRowsAreThoseOfTheLastTwoSteps) {
  const Rollout r = roll("small");
  const Model& m = *r.w.model;
  KvCache cache = m.new_cache();
  for (const auto& batch : r.probe.batches) {
    std::vector<DecoderToken> t = batch;
    m.decode(*r.w.map, cache, t);
    for (const auto& [key, e] : cache.poseless) EXPECT_GE(e.last_step, t.back().step - 1);
  }
  // Kept queries do no cross-attention work in their first layer, and the count says so.
  EXPECT_GT(cache.work.kept_cross_queries, 0);
}

}  // namespace
}  // namespace ss
