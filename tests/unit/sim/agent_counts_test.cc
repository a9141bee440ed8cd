// Full mode given the agents to place per type (SessionOptions::agent_counts): exactly that many of each type at the
// first step, the SDC taken from the log, no two boxes overlapping, nobody joining or retiring later; bad counts
// refused with a message naming them; the counts survive save and restore.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

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

// SessionOptions::placement_room: braking at 6 m/s^2 along its velocity, every placed agent stops short of every
// other moving on at its velocity (checked here every 0.02 s, finer than the session's metre), and moved back along
// its velocity over the last second it clears the SDC's logged boxes.
TEST_F(AgentCounts, PlacementRoomLeavesEveryAgentRoomToStop) {
  const Scenario& sc = *w().scenario;
  const Track& sdc = sc.tracks[sc.sdc_track_index];
  const int now = sc.current_time_index;
  const auto stops_short = [](const StepState& a, const StepState& o) {
    const double v = std::hypot(a.vx, a.vy);
    if (v < 0.1) return true;
    const double t_stop = v / 6.0;
    for (double t = 0.02; t <= t_stop; t += 0.02) {
      const double d = v * t - 3.0 * t * t;
      Box ba = box_of(a), bo = box_of(o);
      ba.pose.x += d * a.vx / v, ba.pose.y += d * a.vy / v;
      bo.pose.x += t * o.vx, bo.pose.y += t * o.vy;
      // A sliver between two of the session's samples (about a metre apart) is not a fault it could see.
      ba.length -= 0.5, ba.width -= 0.1;
      if (boxes_overlap(ba, bo)) return false;
    }
    return true;
  };
  for (uint64_t seed : {1, 2, 3}) {
    SessionOptions o = by_count({6, 3, 1}, seed);
    o.placement_room = true;
    auto s = testing::start(w(), o);
    ASSERT_NE(s, nullptr);
    const StepResult first = s->current();
    EXPECT_EQ(counts_of(first, sdc.id), (std::array<int, 3>{6, 3, 1})) << "seed " << seed;
    for (const AgentView& a : first.agents)
      for (const AgentView& b : first.agents)
        if (a.id != b.id) EXPECT_TRUE(stops_short(a.state, b.state)) << "seed " << seed << ": " << a.id << " into " << b.id;
    for (const AgentView& a : first.agents) {
      if (a.id == sdc.id) continue;
      for (int f = now - 10; f < now; ++f) {
        const ObjectState& p = sdc.states[f];
        if (!p.valid) continue;
        Box b = box_of(a.state);
        b.pose.x -= (now - f) * 0.1 * a.state.vx, b.pose.y -= (now - f) * 0.1 * a.state.vy;
        EXPECT_FALSE(boxes_overlap(b, {{p.x, p.y, p.heading}, p.length, p.width}))
            << "seed " << seed << ": agent " << a.id << " moved back to frame " << f << " meets the SDC";
      }
    }
  }
}

// SessionOptions::pedestrian_contact: the reject sampler leaves pedestrian pairs alone, so random weights' walkers
// run into each other as they do without reject sampling, where with it they hardly do; both survive a snapshot.
TEST_F(AgentCounts, PedestrianContactLetsWalkersTouch) {
  const auto new_touches = [&](bool contact) {
    int n = 0;
    for (uint64_t seed = 1; seed <= 8; ++seed) {
      SessionOptions o = by_count({0, 40, 0}, seed);
      o.pedestrian_contact = contact;
      auto s = testing::start(w(), o);
      EXPECT_NE(s, nullptr);
      if (!s) return -1;
      StepResult before = s->current();
      for (int step = 0; step < 10; ++step) {
        auto r = s->step({});
        EXPECT_TRUE(r.ok()) << r.status();
        if (!r.ok()) return -1;
        for (size_t i = 0; i < r->agents.size(); ++i)
          for (size_t j = i + 1; j < r->agents.size(); ++j) {
            const AgentView &a = r->agents[i], &b = r->agents[j];
            if (a.type != 1 || b.type != 1) continue;
            const auto was = [&](int64_t id) {
              return *std::find_if(before.agents.begin(), before.agents.end(), [&](const AgentView& v) { return v.id == id; });
            };
            if (!boxes_overlap(box_of(was(a.id).state), box_of(was(b.id).state)) &&
                boxes_overlap(box_of(a.state), box_of(b.state)))
              ++n;
          }
        before = *r;
      }
    }
    return n;
  };
  const int apart = new_touches(false), contact = new_touches(true);
  std::printf("pedestrians newly touching: %d without contact, %d with\n", apart, contact);
  EXPECT_GE(contact, 5) << "random walkers should meet for the test to mean anything";
  EXPECT_LE(apart * 3, contact);

  SessionOptions o = by_count({2, 2, 0});
  o.placement_room = o.pedestrian_contact = true;
  auto s = testing::start(w(), o);
  ASSERT_NE(s, nullptr);
  auto r = Session::restore(w().model, w().scenario, w().map, s->save());
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE((*r)->options().placement_room);
  EXPECT_TRUE((*r)->options().pedestrian_contact);
}

}  // namespace
}  // namespace ss
