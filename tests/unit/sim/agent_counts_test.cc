// Full mode given the agents to place per type (SessionOptions::agent_counts): exactly that many of each type at the
// first step, the SDC taken from the log, no two boxes overlapping, nobody joining or retiring later; bad counts
// refused with a message naming them; the counts survive save and restore.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>

#include "engine/geometry/geometry.h"
#include "engine/tokens/resample.h"
#include "tests/unit/sim/session_fixture.h"

namespace ss {
namespace {

using testing::SmallWorldTest;

class AgentCounts : public SmallWorldTest {};

SessionOptions by_count(std::vector<int> counts, uint64_t seed = 7) {
  SessionOptions o;
  o.mode = SessionMode::full;
  o.control_sdc = false;  // the model drives the SDC after the first step
  o.seed = seed;
  o.agent_counts = std::move(counts);
  return o;
}

std::array<int, 3> counts_of(const StepResult& r, int64_t except) {
  std::array<int, 3> c{};
  for (const AgentView& a : r.agents)
    if (a.id != except) ++c[a.type];
  return c;
}

TEST_F(AgentCounts, PlacesExactlyTheRequestedAgentsAroundTheLoggedSdc) {
  const Track& sdc = w().scenario->tracks[w().scenario->sdc_track_index];
  for (uint64_t seed : {1, 2, 3}) {
    auto s = testing::start(w(), by_count({6, 3, 1}, seed));
    ASSERT_NE(s, nullptr);
    const StepResult first = s->current();
    EXPECT_EQ(counts_of(first, sdc.id), (std::array<int, 3>{6, 3, 1})) << "seed " << seed;
    ASSERT_EQ(first.agents.size(), 11u);
    // The SDC is the log's at the current frame, and not controlled: the model drives it.
    const auto it = std::find_if(first.agents.begin(), first.agents.end(), [&](const AgentView& a) { return a.id == sdc.id; });
    ASSERT_NE(it, first.agents.end());
    EXPECT_FALSE(it->controlled);
    EXPECT_NEAR(it->state.x, sdc.states[w().scenario->current_time_index].x, 1e-3);
    for (size_t i = 0; i < first.agents.size(); ++i)
      for (size_t j = i + 1; j < first.agents.size(); ++j)
        EXPECT_FALSE(boxes_overlap(box_of(first.agents[i].state), box_of(first.agents[j].state)))
            << "seed " << seed << ": agents " << first.agents[i].id << " and " << first.agents[j].id;
    // Nobody joins or retires later: the scene stays the requested agents.
    for (int k = 0; k < 4; ++k) {
      auto r = s->step({});
      ASSERT_TRUE(r.ok()) << r.status();
      EXPECT_EQ(counts_of(*r, sdc.id), (std::array<int, 3>{6, 3, 1}));
      EXPECT_TRUE(r->left.empty());
    }
  }
}

TEST_F(AgentCounts, ZeroCountsPlaceOnlyTheSdc) {
  auto s = testing::start(w(), by_count({0, 0, 0}));
  ASSERT_NE(s, nullptr);
  ASSERT_EQ(s->current().agents.size(), 1u);
  EXPECT_EQ(s->current().agents[0].id, w().scenario->tracks[w().scenario->sdc_track_index].id);
}

TEST_F(AgentCounts, BadCountsAreRefusedByName) {
  auto message = [&](SessionOptions o) {
    auto s = Session::create(w().model, w().scenario, w().map, o);
    EXPECT_FALSE(s.ok());
    return s.ok() ? std::string() : std::string(s.status().message());
  };
  EXPECT_NE(message(by_count({1, 2})).find("needs 3"), std::string::npos);
  EXPECT_NE(message(by_count({1, -1, 0})).find("agent_counts[1] -1"), std::string::npos);
  SessionOptions motion = by_count({1, 1, 1});
  motion.mode = SessionMode::motion;
  EXPECT_NE(message(motion).find("only full mode"), std::string::npos);
  SessionOptions capped = by_count({10, 0, 0});
  capped.max_agents = 10;  // 10 placed and the SDC make 11
  EXPECT_NE(message(capped).find("more than max_agents (10)"), std::string::npos);
}

TEST_F(AgentCounts, CountsSurviveSaveAndRestore) {
  auto s = testing::start(w(), by_count({4, 1, 0}));
  ASSERT_NE(s, nullptr);
  ASSERT_TRUE(s->step({}).ok());
  auto r = Session::restore(w().model, w().scenario, w().map, s->save());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ((*r)->options().agent_counts, (std::vector<int>{4, 1, 0}));
  auto a = s->step({});
  auto b = (*r)->step({});
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_TRUE(testing::same_result(*a, *b));
}

}  // namespace
}  // namespace ss
