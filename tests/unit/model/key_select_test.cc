#include "engine/model/key_select.h"

#include <gtest/gtest.h>

#include <random>

namespace ss {
namespace {

// A session's sequence as the decoder sees it: per step the lights, the agent-state group (SOS, each agent's SOA,
// TYPE, MS and RS, EOS), then a motion token per agent. Agents and lights are scattered over 120 m, so that the
// neighbour limit below cuts both by count and by radius.
std::vector<DecoderToken> sequence(int steps, int agents, int lights, std::mt19937& rng) {
  std::uniform_real_distribution<double> where(-60, 60), heading(-3, 3);
  std::vector<DecoderToken> out;
  auto add = [&](TokenKind kind, int step, int64_t object, bool posed) {
    DecoderToken t;
    t.kind = kind;
    t.step = step;
    t.object = object;
    t.seq = static_cast<int64_t>(out.size());
    t.has_pose = posed;
    if (posed) t.pose = {where(rng), where(rng), heading(rng)};
    out.push_back(t);
  };
  for (int s = 0; s < steps; ++s) {
    for (int l = 0; l < lights; ++l) add(TokenKind::light, s, light_object(l), true);
    add(TokenKind::sos, s, kNoObject, false);
    for (int a = 0; a < agents - (s % 3); ++a) {  // agents come and go
      add(TokenKind::soa, s, a, false);
      add(TokenKind::type, s, a, false);
      add(TokenKind::map_segment, s, a, true);
      add(TokenKind::relative_state, s, a, true);
    }
    add(TokenKind::eos, s, kNoObject, false);
    for (int a = 0; a < agents - (s % 3); ++a) add(TokenKind::motion, s, a, true);
  }
  return out;
}

// The definition: every token of the sequence the mask allows, the spatial pairs cut to the nearest.
// `dropped`: how many spatial keys the limit cut.
SelfKeys brute_force(std::span<const DecoderToken> all, int q, int window, const NeighbourLimit& limit, int& dropped) {
  const DecoderToken& t = all[q];
  SelfKeys out;
  std::vector<int> spatial;
  std::vector<double> dist;
  std::vector<int64_t> order;
  std::vector<int> kept_spatial;
  for (int j = 0; j < static_cast<int>(all.size()); ++j) {
    const DecoderToken& k = all[j];
    if (!may_attend(t, k, window)) continue;
    if (is_spatial_pair(t, k)) {
      spatial.push_back(j);
      dist.push_back(distance({t.pose.x, t.pose.y}, {k.pose.x, k.pose.y}));
      order.push_back(k.seq);
    }
  }
  for (int pos : nearest_within(dist, order, limit)) kept_spatial.push_back(spatial[pos]);
  dropped = static_cast<int>(spatial.size() - kept_spatial.size());
  for (int j = 0; j < static_cast<int>(all.size()); ++j) {
    const DecoderToken& k = all[j];
    if (!may_attend(t, k, window)) continue;
    if (is_spatial_pair(t, k)) {
      if (std::find(kept_spatial.begin(), kept_spatial.end(), j) != kept_spatial.end()) out.posed.push_back(j);
    } else {
      (t.has_pose && k.has_pose ? out.posed : out.unposed).push_back(j);
    }
  }
  return out;
}

// Every way the decoder splits a sequence into calls (a step's lights, its group, one token of a new agent, its
// motion tokens) gives each fresh token the keys of the definition.
TEST(SelfKeySelector, EveryQueryGetsTheKeysTheMaskAndTheLimitDefine) {
  std::mt19937 rng(7);
  const std::vector<DecoderToken> all = sequence(9, 12, 3, rng);
  const NeighbourLimit limit{6, 30.0, 3};
  const int window = 4;
  int checked = 0, cut = 0;
  for (size_t first = 0; first < all.size();) {
    // The call: one token where it starts at a multiple of three (a new agent's tokens come one call at a time),
    // else the run of tokens of one kind class at one step (a step's lights, its group, its motion).
    size_t last = first + 1;
    auto kind_class = [](const DecoderToken& t) { return is_agent_state_group(t.kind) ? 1 : static_cast<int>(t.kind); };
    if (first % 3 != 0)
      while (last < all.size() && all[last].step == all[first].step &&
             kind_class(all[last]) == kind_class(all[first]))
        ++last;
    const std::span<const DecoderToken> cached(all.data(), first), fresh(all.data() + first, last - first);
    SelfKeySelector selector(cached, fresh, window, limit);
    SelfKeys got;
    for (size_t i = 0; i < fresh.size(); ++i) {
      selector.select(static_cast<int>(i), got);
      int dropped = 0;
      const SelfKeys want =
          brute_force(std::span(all.data(), last), static_cast<int>(first + i), window, limit, dropped);
      ASSERT_EQ(got.posed, want.posed) << "query " << first + i;
      ASSERT_EQ(got.unposed, want.unposed) << "query " << first + i;
      ++checked;
      cut += dropped > 0;
    }
    first = last;
  }
  EXPECT_GT(checked, 400);
  EXPECT_GT(cut, 100);  // the limit did cut
}

}  // namespace
}  // namespace ss
