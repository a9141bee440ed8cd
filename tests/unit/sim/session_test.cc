#include "engine/sim/session.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <thread>

#include "engine/io/record.h"
#include "engine/sim/events.h"
#include "engine/sim/map_cache.h"
#include "engine/tokens/fidelity.h"
#include "state/session_state.pb.h"
#include "tests/unit/sim/session_fixture.h"

namespace ss {
namespace {

using testing::load_world;
using testing::roll;
using testing::same_rollout;
using testing::same_result;
using testing::sdc_control;
using testing::start;

class SessionTest : public testing::SmallWorldTest {};

TEST_F(SessionTest, MotionModeStartsFromTheLogAtTheCurrentStep) {
  SessionOptions o;
  auto s = start(w(), o);
  ASSERT_TRUE(s);
  const StepResult r = s->current();
  EXPECT_EQ(r.step, 2);
  EXPECT_DOUBLE_EQ(r.time, 1.0);
  // Every modelled log agent valid at frame 10 within the region, the SDC controlled.
  int expected = 0;
  const Track& sdc = w().scenario->tracks[w().scenario->sdc_track_index];
  for (const Track& t : w().scenario->tracks)
    if (model_type(t.type) >= 0 && t.states[10].valid &&
        std::hypot(t.states[10].x - sdc.states[10].x, t.states[10].y - sdc.states[10].y) <= o.roi_radius)
      ++expected;
  EXPECT_EQ(static_cast<int>(r.agents.size()), expected);
  int controlled = 0;
  for (const AgentView& a : r.agents) {
    if (a.controlled) {
      ++controlled;
      EXPECT_EQ(a.id, sdc.id);
      EXPECT_NEAR(a.state.x, sdc.states[10].x, 1e-6);
    }
  }
  EXPECT_EQ(controlled, 1);
  EXPECT_FALSE(r.lights.empty());
}

TEST_F(SessionTest, MotionModeFollowsControlsAndAddsNoAgents) {
  auto s = start(w(), {});
  const size_t initial = s->current().agents.size();
  std::set<int64_t> ids;
  for (const AgentView& a : s->current().agents) ids.insert(a.id);
  for (const StepResult& r : roll(*s, w(), 10)) {
    for (const AgentView& a : r.agents) {
      EXPECT_TRUE(ids.count(a.id)) << "motion mode must not add agents";
      if (a.controlled) {
        const ControlInput c = sdc_control(w(), r.step);
        EXPECT_NEAR(a.state.x, c.x, 1e-9);
        EXPECT_NEAR(a.state.y, c.y, 1e-9);
      }
    }
    EXPECT_LE(r.agents.size(), initial);
  }
}

TEST_F(SessionTest, SameSeedSameRolloutOtherSeedAnother) {
  for (SessionMode mode : {SessionMode::motion, SessionMode::full}) {
    SessionOptions o;
    o.mode = mode;
    o.seed = 5;
    auto a = start(w(), o), b = start(w(), o);
    o.seed = 6;
    auto c = start(w(), o);
    const auto ra = roll(*a, w(), 6), rb = roll(*b, w(), 6), rc = roll(*c, w(), 6);
    EXPECT_TRUE(same_rollout(ra, rb)) << session_mode_name(mode);
    EXPECT_FALSE(same_rollout(ra, rc)) << session_mode_name(mode);
  }
}

// `sessions` sessions of `w` with options `o`, each rolled `steps` steps on its own thread, all at once.
std::vector<std::vector<StepResult>> rollouts_at_once(const testing::World& w, const SessionOptions& o, int sessions,
                                                      int steps) {
  std::vector<std::vector<StepResult>> results(sessions);
  std::vector<std::thread> threads;
  for (int t = 0; t < sessions; ++t)
    threads.emplace_back([&, t] {
      auto s = start(w, o);
      results[t] = roll(*s, w, steps);
    });
  for (auto& t : threads) t.join();
  return results;
}

TEST_F(SessionTest, SameRolloutWhateverTheThreadCount) {
  SessionOptions o;
  o.mode = SessionMode::full;
  o.seed = 9;
  auto alone = start(w(), o);
  const auto reference = roll(*alone, w(), 5);
  // Four sessions stepped on four threads at once give the reference rollout, bit for bit.
  for (const auto& r : rollouts_at_once(w(), o, 4, 5)) EXPECT_TRUE(same_rollout(reference, r));
}

TEST_F(SessionTest, StepThreadsGiveTheSameRollout) {
  SessionOptions o;
  o.mode = SessionMode::full;
  o.seed = 9;
  auto alone = start(w(), o);
  const auto reference = roll(*alone, w(), 5);
  // The same weights with three threads per decode call: a lone session, then two at once (whichever finds the
  // pool busy runs its attention on its own thread).
  ModelOptions threaded;
  threaded.step_threads = 3;
  auto model = Model::create(w().model->weights(), threaded);
  ASSERT_TRUE(model.ok()) << model.status();
  ASSERT_EQ((*model)->step_threads(), 3);
  testing::World w3 = w();
  w3.model = *model;
  auto lone = start(w3, o);
  EXPECT_TRUE(same_rollout(reference, roll(*lone, w3, 5)));
  for (const auto& r : rollouts_at_once(w3, o, 2, 5)) EXPECT_TRUE(same_rollout(reference, r));
  threaded.step_threads = 0;
  EXPECT_FALSE(Model::create(w().model->weights(), threaded).ok());
}

// Reject sampling of motion (SessionOptions::motion_reject): with random weights agents wander into each other and
// off the road; with it on, far fewer do so, and what it changes is only how controls are drawn.
TEST_F(SessionTest, MotionRejectKeepsAgentsApartAndVehiclesOnTheRoad) {
  const EventMap map = event_map_from_scenario(*w().scenario);
  const auto box = [](const AgentView& a) {
    return Box{{a.state.x, a.state.y, a.state.heading}, a.state.length, a.state.width};
  };
  const auto on_road = [&](const AgentView& a) {
    for (const Vec2& c : box_corners(box(a)))
      if (map.edges.signed_distance(c.x, c.y, 0) > 0) return false;
    return true;
  };
  struct Faults {
    int overlaps = 0, off_road = 0;
  };
  // Summed over four seeds: one rollout's few overlaps are too few to compare.
  uint64_t seed = 0;
  const auto run = [&](bool reject, Faults& f) {
    SessionOptions o;
    o.seed = seed;
    o.control_sdc = false;
    o.motion_reject = reject;
    auto s = start(w(), o);
    StepResult before = s->current();
    for (int step = 0; step < 8; ++step) {
      auto r = s->step({});
      EXPECT_TRUE(r.ok()) << r.status();
      std::map<int64_t, const AgentView*> was;
      for (const AgentView& a : before.agents) was[a.id] = &a;
      for (size_t i = 0; i < r->agents.size(); ++i) {
        const AgentView& a = r->agents[i];
        if (!was.count(a.id)) continue;
        if (a.type == 0 && on_road(*was[a.id]) && !on_road(a)) ++f.off_road;
        for (size_t j = i + 1; j < r->agents.size(); ++j) {
          const AgentView& b = r->agents[j];
          if (was.count(b.id) && !boxes_overlap(box(*was[a.id]), box(*was[b.id])) && boxes_overlap(box(a), box(b)))
            ++f.overlaps;
        }
      }
      before = *r;
    }
  };
  Faults off, on;
  for (seed = 4; seed < 8; ++seed) {
    run(false, off);
    run(true, on);
  }
  EXPECT_GE(off.overlaps, 10) << "random weights should make collisions for the test to mean anything";
  EXPECT_GE(off.off_road, 10);
  EXPECT_LE(on.overlaps * 4, off.overlaps)
      << on.overlaps << " new overlaps with reject sampling, " << off.overlaps << " without";
  EXPECT_LE(on.off_road * 3, off.off_road)
      << on.off_road << " vehicles left the road with reject sampling, " << off.off_road << " without";
  std::printf("new overlaps %d -> %d, vehicles leaving the road %d -> %d\n", off.overlaps, on.overlaps, off.off_road,
              on.off_road);
}

TEST_F(SessionTest, FullModeGeneratesItsOwnAgents) {
  SessionOptions o;
  o.mode = SessionMode::full;
  o.seed = 3;
  auto s = start(w(), o);
  const StepResult r = s->current();
  ASSERT_GE(r.agents.size(), 1u);
  EXPECT_TRUE(r.agents[0].controlled);
  // The token sequence begins at the current step, as a training sequence begins where its agents first appear:
  // no history steps holding the controlled agent alone.
  for (const DecoderToken& t : s->cache().tokens) {
    EXPECT_EQ(t.step, r.step) << "a token of an earlier step";
    if (t.kind == TokenKind::motion && t.object == r.agents[0].id) EXPECT_EQ(t.motion_action, kMotionStart);
  }
  const int64_t max_log_id = [&] {
    int64_t m = 0;
    for (const Track& t : w().scenario->tracks) m = std::max<int64_t>(m, t.id);
    return m;
  }();
  for (size_t i = 1; i < r.agents.size(); ++i) {
    EXPECT_GT(r.agents[i].id, max_log_id) << "generated agents get fresh ids";
    EXPECT_TRUE(r.agents[i].entered);
    EXPECT_LE(std::hypot(r.agents[i].state.x - r.agents[0].state.x, r.agents[i].state.y - r.agents[0].state.y),
              o.roi_radius + 20);  // spawned on a segment within the region (segment centre + offset)
  }
}

TEST_F(SessionTest, DensifyReachesItsTarget) {
  SessionOptions o;
  o.mode = SessionMode::densify;
  o.roi_radius = 60;
  auto base = start(w(), o);
  const int log_agents = static_cast<int>(base->current().agents.size());
  o.densify_target = log_agents + 5;
  auto s = start(w(), o);
  EXPECT_EQ(static_cast<int>(s->current().agents.size()), o.densify_target);
}

TEST_F(SessionTest, DensifyInACrowdedRegionEndsWithoutOverlaps) {
  // A region too small for the target: agents that find no free place are dropped, and a run of such drops ends
  // the group, so creation ends with the new agents apart from every other.
  SessionOptions o;
  o.mode = SessionMode::densify;
  o.roi_radius = 12;
  o.densify_target = 120;
  auto s = start(w(), o);
  ASSERT_TRUE(s);
  const StepResult r = s->current();
  EXPECT_LT(static_cast<int>(r.agents.size()), o.densify_target);
  const auto box = [](const AgentView& a) {
    return Box{{a.state.x, a.state.y, a.state.heading}, a.state.length, a.state.width};
  };
  for (size_t i = 0; i < r.agents.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (r.agents[i].entered) EXPECT_FALSE(boxes_overlap(box(r.agents[i]), box(r.agents[j]))) << i << " and " << j;
}

TEST_F(SessionTest, InjectSampledAgentsOfATypeNearAPoint) {
  auto s = start(w(), {});
  const AgentView ego = s->current().agents[0];
  InjectRequest req;
  req.count = 3;
  req.type = 1;
  req.near = Vec2{ego.state.x, ego.state.y};
  req.near_radius = 30;
  auto ids = s->inject(req);
  ASSERT_TRUE(ids.ok()) << ids.status();
  ASSERT_EQ(ids->size(), 3u);
  const StepResult r = s->current();
  for (int64_t id : *ids) {
    auto it = std::find_if(r.agents.begin(), r.agents.end(), [&](const AgentView& a) { return a.id == id; });
    ASSERT_NE(it, r.agents.end());
    EXPECT_EQ(it->type, 1);
    EXPECT_TRUE(it->entered);
    EXPECT_LT(std::hypot(it->state.x - ego.state.x, it->state.y - ego.state.y), 30 + 15);
  }
  // The injected agents move on with everyone else.
  auto next = s->step({sdc_control(w(), 3)});
  ASSERT_TRUE(next.ok());
  for (int64_t id : *ids)
    EXPECT_TRUE(std::any_of(next->agents.begin(), next->agents.end(), [&](const AgentView& a) { return a.id == id; }) ||
                std::count(next->left.begin(), next->left.end(), id));
}

TEST_F(SessionTest, InjectAnExactState) {
  auto s = start(w(), {});
  const AgentView ego = s->current().agents[0];
  StepState st{ego.state.x + 30, ego.state.y - 30, 0.5, 3, 1, 4.5, 2, 1.6, true};
  InjectRequest req;
  req.state = st;
  req.type = 2;
  auto ids = s->inject(req);
  ASSERT_TRUE(ids.ok()) << ids.status();
  const StepResult r = s->current();
  auto it = std::find_if(r.agents.begin(), r.agents.end(), [&](const AgentView& a) { return a.id == ids->at(0); });
  ASSERT_NE(it, r.agents.end());
  EXPECT_EQ(it->state, st);
  EXPECT_EQ(it->type, 2);
}

TEST_F(SessionTest, InjectRejectsBadRequestsAndLeavesTheSessionAsItWas) {
  auto s = start(w(), {});
  const std::string before = s->save();
  InjectRequest bad_type;
  bad_type.count = 1;
  bad_type.type = 3;
  EXPECT_EQ(s->inject(bad_type).status().code(), absl::StatusCode::kInvalidArgument);
  InjectRequest nan_state;
  nan_state.state = StepState{std::numeric_limits<double>::quiet_NaN(), 0, 0, 0, 0, 4, 2, 1.5, true};
  EXPECT_EQ(s->inject(nan_state).status().code(), absl::StatusCode::kInvalidArgument);
  InjectRequest zero;
  EXPECT_EQ(s->inject(zero).status().code(), absl::StatusCode::kInvalidArgument);
  InjectRequest far;
  far.count = 1;
  far.near = Vec2{1e6, 1e6};  // no segment within the region there
  EXPECT_EQ(s->inject(far).status().code(), absl::StatusCode::kResourceExhausted);
  InjectRequest too_many;
  too_many.count = 128;
  EXPECT_EQ(s->inject(too_many).status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(s->save(), before);
}

TEST_F(SessionTest, StateForceTeleportsAgentsAndSetsLights) {
  auto s = start(w(), {});
  const StepResult r0 = s->current();
  const AgentView other = r0.agents[1];
  StepState target = other.state;
  target.x += 5;
  target.y -= 3;
  StateForceRequest req;
  req.agents = {{other.id, target}};
  const LightState forced = r0.lights[0].state == LightState::red ? LightState::green : LightState::red;
  req.lights = {{r0.lights[0].lane, forced}};
  ASSERT_TRUE(s->state_force(req).ok());
  auto r1 = s->step({sdc_control(w(), 3)});
  ASSERT_TRUE(r1.ok());
  auto it = std::find_if(r1->agents.begin(), r1->agents.end(), [&](const AgentView& a) { return a.id == other.id; });
  ASSERT_NE(it, r1->agents.end());
  EXPECT_EQ(it->state, target);
  EXPECT_EQ(r1->lights[0].state, forced);

  const std::string before = s->save();
  StateForceRequest unknown;
  unknown.agents = {{999999, target}};
  EXPECT_EQ(s->state_force(unknown).code(), absl::StatusCode::kInvalidArgument);
  StateForceRequest bad_lane;
  bad_lane.lights = {{-42, LightState::red}};
  EXPECT_EQ(s->state_force(bad_lane).code(), absl::StatusCode::kInvalidArgument);
  StateForceRequest nan;
  target.heading = std::numeric_limits<double>::infinity();
  nan.agents = {{other.id, target}};
  EXPECT_EQ(s->state_force(nan).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(s->save(), before);
}

TEST_F(SessionTest, BadControlsAreRefusedAndChangeNothing) {
  auto s = start(w(), {});
  const std::string before = s->save();
  ControlInput c = sdc_control(w(), 3);
  ControlInput nan = c;
  nan.x = std::numeric_limits<double>::quiet_NaN();
  ControlInput jump = c;
  jump.x += 500;
  ControlInput unknown = c;
  unknown.agent_id = 123456789;
  ControlInput not_controlled = c;
  not_controlled.agent_id = s->current().agents[1].id;
  ControlInput huge_heading = c;
  huge_heading.heading = 1e308;
  ControlInput backwards = c;
  backwards.speed = -50;
  for (const ControlInput& bad : {nan, jump, unknown, not_controlled, huge_heading, backwards}) {
    auto r = s->step({bad});
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_FALSE(r.status().message().empty());
  }
  EXPECT_EQ(s->step({c, c}).status().code(), absl::StatusCode::kInvalidArgument);  // twice
  EXPECT_EQ(s->save(), before);
  EXPECT_TRUE(s->step({c}).ok());
}

TEST_F(SessionTest, ForkCopiesEverythingThenEvolvesIndependently) {
  SessionOptions o;
  o.mode = SessionMode::full;
  auto s = start(w(), o);
  roll(*s, w(), 2);
  auto copy = s->fork();
  // Same inputs: the copy continues exactly as the original (cache and RNG copied).
  const auto a = roll(*s, w(), 4);
  const auto b = roll(*copy, w(), 4);
  EXPECT_TRUE(same_rollout(a, b));
  // Stepping one does not move the other.
  const int step = copy->step_index();
  roll(*s, w(), 2);
  EXPECT_EQ(copy->step_index(), step);
  // Different inputs: different futures.
  StateForceRequest teleport;
  StepState st = copy->current().agents[0].state;
  st.x += 20;
  teleport.agents = {{copy->current().agents[0].id, st}};
  ASSERT_TRUE(copy->state_force(teleport).ok());
  EXPECT_NE(copy->step({}).value().agents[0].state.x, s->current().agents[0].state.x);
}

TEST_F(SessionTest, SaveRestoreContinuesIdentically) {
  for (SessionMode mode : {SessionMode::motion, SessionMode::full}) {
    SessionOptions o;
    o.mode = mode;
    o.seed = 21;
    o.roi_radius = 60;
    auto s = start(w(), o);
    roll(*s, w(), 24);  // well past L * (W - 1) steps, so the saved batches are a suffix of the history
    const std::string bytes = s->save();
    auto restored = Session::restore(w().model, w().scenario, w().map, bytes);
    ASSERT_TRUE(restored.ok()) << restored.status();
    EXPECT_EQ((*restored)->save(), bytes);
    EXPECT_TRUE(same_result(s->current(), (*restored)->current()));
    const auto a = roll(*s, w(), 8);
    const auto b = roll(**restored, w(), 8);
    EXPECT_TRUE(same_rollout(a, b)) << session_mode_name(mode);
    std::printf("%s: snapshot of %zu bytes at step 26\n", session_mode_name(mode), bytes.size());
  }
}

// The 10 Hz clock is the session's: poses pushed between model steps are part of its state (saved, forked) and are
// checked when they arrive.
TEST_F(SessionTest, TenHzPosesPushedBetweenStepsSurviveSaveAndRestore) {
  SessionOptions o;
  o.tick_hz = 10;
  o.seed = 4;
  auto s = start(w(), o);
  const int64_t sdc = w().scenario->tracks[w().scenario->sdc_track_index].id;
  auto pose_at = [&](const Session& session, int k) {
    const StepResult v = session.tick_view();
    for (const AgentView& a : v.agents)
      if (a.id == sdc) return ControlInput{sdc, a.state.x + 0.1 * a.state.vx + 0.05 * k, a.state.y + 0.1 * a.state.vy,
                                           a.state.heading + 0.01, std::nullopt};
    return ControlInput{};
  };
  for (int k = 0; k < 7; ++k) ASSERT_TRUE(s->tick({pose_at(*s, k)}).ok());
  EXPECT_EQ(s->tick_index(), 7);
  EXPECT_EQ(s->step_index(), w().scenario->current_time_index / 5 + 1);
  auto restored = Session::restore(w().model, w().scenario, w().map, s->save());
  ASSERT_TRUE(restored.ok()) << restored.status();
  EXPECT_EQ((*restored)->tick_index(), 7);
  EXPECT_TRUE(same_result(s->tick_view(), (*restored)->tick_view()));
  for (int k = 7; k < 13; ++k) {
    auto a = s->tick({pose_at(*s, k)});
    auto b = (*restored)->tick({pose_at(**restored, k)});
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_TRUE(same_result(*a, *b)) << "tick " << k + 1;
  }
}

// The tick reports each controlled agent's events, measured from the tick before it by events.h's rules, at 2 and
// 10 Hz; views carry none, a fork shares its source's event map, and a session without controlled agents has none.
TEST_F(SessionTest, TicksCarryTheControlledAgentsEvents) {
  const EventMap m = event_map_from_scenario(*w().scenario);
  const int64_t sdc = w().scenario->tracks[w().scenario->sdc_track_index].id;
  auto same = [](const AgentEvents& a, const AgentEvents& b) {
    const bool same_edge = a.road_edge_distance == b.road_edge_distance ||
                           (std::isnan(a.road_edge_distance) && std::isnan(b.road_edge_distance));
    return a.agent_id == b.agent_id && a.overlapping == b.overlapping && same_edge && a.off_road == b.off_road &&
           a.ran_red_light == b.ran_red_light && a.red_light_lane == b.red_light_lane &&
           a.lane.lane_id == b.lane.lane_id && a.lane.s == b.lane.s && a.lane.offset == b.lane.offset &&
           a.progress == b.progress;
  };
  for (int hz : {2, 10}) {
    SessionOptions o;
    o.tick_hz = hz;
    auto s = start(w(), o);
    double progress = 0;
    for (int k = 0; k < 6; ++k) {
      const StepResult before = s->tick_view();
      auto r = s->tick({sdc_control(w(), s->step_index() + 1)});  // the SDC along its log
      ASSERT_TRUE(r.ok()) << r.status();
      const std::vector<AgentEvents> expected = tick_events(m, before, *r);
      ASSERT_EQ(r->events.size(), 1u) << hz << " Hz, tick " << k + 1;
      EXPECT_EQ(r->events[0].agent_id, sdc);
      EXPECT_TRUE(same(r->events[0], expected[0])) << hz << " Hz, tick " << k + 1;
      progress += r->events[0].progress;
    }
    EXPECT_GT(progress, 0) << hz << " Hz: the SDC follows its log along its lane";
    EXPECT_TRUE(s->tick_view().events.empty());
    EXPECT_TRUE(s->current().events.empty());
    auto copy = s->fork();
    EXPECT_EQ(copy->event_map(), s->event_map());
  }
  SessionOptions none;
  none.control_sdc = false;
  none.motion_reject = false;  // reject sampling reads the event map's road edges
  auto s = start(w(), none);
  auto r = s->tick({});
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_TRUE(r->events.empty());
  EXPECT_EQ(s->event_map(), nullptr);  // not built when no agent is controlled
}

TEST_F(SessionTest, TenHzPosesAreCheckedWhenTheyArrive) {
  SessionOptions o;
  o.tick_hz = 10;
  auto s = start(w(), o);
  ControlInput far = sdc_control(w(), 2);
  far.x += 5000;  // once accepted between model steps, shown, then failing the step two ticks later
  const std::string before = s->save();
  auto r = s->tick({far});
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("from the last one"), std::string::npos) << r.status();
  EXPECT_EQ(s->save(), before);
  for (int k = 0; k < 5; ++k) EXPECT_TRUE(s->tick({}).ok());  // the model step at the fifth tick included
  EXPECT_EQ(s->tick_index(), 5);
}

TEST_F(SessionTest, AnOlderStateFormatIsRefusedNamingBothVersions) {
  auto s = start(w(), {});
  const RecordFormat now{"SSSESSN3", 1, "session snapshot", "engine"};
  const RecordFormat older{"SSSESSN2", 1, "session snapshot", "engine"};
  auto message = record_read(now, s->save());
  ASSERT_TRUE(message.ok()) << message.status();
  auto r = Session::restore(w().model, w().scenario, w().map, record_write(older, *message));
  EXPECT_EQ(r.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("version 2 is not this engine's version 3"), std::string::npos) << r.status();
}

// The layout before the one framed record: the magic, the message's FNV-1a hash, the message. Still restored.
TEST_F(SessionTest, AStateInTheLayoutBeforeTheFramingRestores) {
  auto s = start(w(), {});
  roll(*s, w(), 3);
  auto message = record_read({"SSSESSN3", 1, "session snapshot", "engine"}, s->save());
  ASSERT_TRUE(message.ok()) << message.status();
  std::string earlier = "SSSESSN3";
  for (uint64_t h = fnv1a64(*message), i = 0; i < 8; ++i) earlier += static_cast<char>((h >> (8 * i)) & 0xff);
  earlier += *message;
  auto r = Session::restore(w().model, w().scenario, w().map, earlier);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ((*r)->save(), s->save());
  earlier[20] = static_cast<char>(earlier[20] ^ 1);
  EXPECT_EQ(Session::restore(w().model, w().scenario, w().map, earlier).status().code(), absl::StatusCode::kDataLoss);
}

TEST_F(SessionTest, RestoreRefusesCorruptBytes) {
  auto s = start(w(), {});
  roll(*s, w(), 3);
  const std::string bytes = s->save();
  EXPECT_FALSE(Session::restore(w().model, w().scenario, w().map, "nonsense").ok());
  // Cut anywhere (a protobuf message cut at a field boundary still parses) or with a flipped bit: refused.
  for (size_t n : {size_t{12}, bytes.size() / 2, bytes.size() - 1}) {
    auto r = Session::restore(w().model, w().scenario, w().map, bytes.substr(0, n));
    EXPECT_FALSE(r.ok()) << "cut at " << n;
  }
  for (size_t i = 8; i < bytes.size(); i += bytes.size() / 16) {
    std::string b = bytes;
    b[i] = static_cast<char>(b[i] ^ 0x04);
    auto r = Session::restore(w().model, w().scenario, w().map, b);
    EXPECT_EQ(r.status().code(), absl::StatusCode::kDataLoss) << "bit flipped at byte " << i << ": " << r.status();
  }
  Scenario other = *w().scenario;
  other.id = "another";
  auto r = Session::restore(w().model, std::make_shared<const Scenario>(other), w().map, bytes);
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("another"), std::string::npos);
}

// The hash catches accidents; a well-formed state with a wrong value (written by hand, or by a bug) is refused by the
// engine's field checks, naming the field.
TEST_F(SessionTest, RestoreChecksEveryFieldOfAWellFormedState) {
  auto s = start(w(), {});
  roll(*s, w(), 3);
  const std::string bytes = s->save();
  const RecordFormat format{"SSSESSN3", 1, "session snapshot", "engine"};
  auto edited = [&](const std::function<void(state::SessionState&)>& edit) {
    state::SessionState m;
    EXPECT_TRUE(m.ParseFromString(*record_read(format, bytes)));
    edit(m);
    return Session::restore(w().model, w().scenario, w().map, record_write(format, m.SerializeAsString()));
  };
  ASSERT_TRUE(edited([](state::SessionState&) {}).ok());  // the unedited message restores
  const std::vector<std::pair<std::string, std::function<void(state::SessionState&)>>> cases = {
      {"tick_hz 3", [](state::SessionState& m) { m.mutable_options()->set_tick_hz(3); }},
      {"options out of range", [](state::SessionState& m) { m.mutable_options()->set_top_p(1.5); }},
      {"has a field out of range", [](state::SessionState& m) { m.mutable_agents(0)->set_type(99); }},
      {"non-finite forced state",
       [](state::SessionState& m) { m.mutable_agents(0)->mutable_forced()->set_x(std::nan("")); }},
      {"not 4 words", [](state::SessionState& m) { m.mutable_rng()->RemoveLast(); }},
      {"slot table", [](state::SessionState& m) { m.clear_slot_used(); }},
      {"a token of step", [](state::SessionState& m) { m.mutable_replay(0)->mutable_tokens(0)->set_map_id(-1); }},
      {"not contiguous", [](state::SessionState& m) { m.mutable_replay()->DeleteSubrange(1, 1); }},
      {"two pushed poses", [](state::SessionState& m) {
         m.add_latest_pose()->set_agent_id(5);
         m.add_latest_pose()->set_agent_id(5);
       }},
      {"saved for scenario elsewhere", [](state::SessionState& m) { m.set_scenario_id("elsewhere"); }},
  };
  for (const auto& [expected, edit] : cases) {
    auto r = edited(edit);
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument) << expected << ": " << r.status();
    EXPECT_NE(r.status().message().find(expected), std::string::npos) << expected << ": " << r.status();
  }
}

TEST_F(SessionTest, MapCacheSharesLiveEncodingsAndForgetsDroppedOnes) {
  MapCache cache(w().model);
  auto a = cache.get(*w().scenario);
  auto b = cache.get(*w().scenario);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->get(), b->get());
  EXPECT_EQ(cache.encodes(), 1);
  // Client-sent scenarios with maps of their own, each dropped by its session before the next arrives: the cache
  // keeps no entry for them (the server's memory under repeated client-sent scenarios, issue 13).
  a->reset();
  b->reset();
  for (int i = 1; i <= 5; ++i) {
    Scenario moved = *w().scenario;
    moved.map_features[0].points[0].x += i;
    auto m = cache.get(moved);
    ASSERT_TRUE(m.ok());
    EXPECT_EQ(cache.entries(), 1u);
  }
  EXPECT_EQ(cache.encodes(), 6);
}

TEST_F(SessionTest, CacheKeepsOnlyTheWindow) {
  SessionOptions o;
  o.window_steps = 4;
  auto s = start(w(), o);
  size_t memory_at_8 = 0;
  for (int i = 0; i < 40; ++i) {
    ASSERT_TRUE(s->step({}).ok());
    // Every cached token belongs to the last 4 steps.
    for (const DecoderToken& t : s->cache().tokens) ASSERT_GT(t.step, s->step_index() - 4);
    if (i == 8) memory_at_8 = s->memory_bytes();
  }
  EXPECT_LE(s->memory_bytes(), memory_at_8 * 11 / 10) << "memory must stay flat once the window is full";
}

TEST_F(SessionTest, CrossKeySetsAreKeptForTheNewestStepOnly) {
  auto s = start(w(), {});
  std::set<const QueryKeys*> before;
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(s->step({}).ok());
    const KvCache& cache = s->cache();
    const int newest = cache.tokens.back().step;
    const StepResult now = s->current();
    // At most one pose per light, per agent's anchor segment and per agent's own pose (its RS and motion tokens).
    EXPECT_LE(cache.cross_keys.size(), now.lights.size() + 2 * now.agents.size());
    std::set<const QueryKeys*> sets;
    for (const auto& [pose, entry] : cache.cross_keys) {
      EXPECT_EQ(entry.last_step, newest);
      sets.insert(entry.keys.get());
    }
    // Lights keep their pose, so their sets are reused from step to step rather than built again.
    ASSERT_FALSE(now.lights.empty()) << "the test scenario needs traffic lights";
    if (i > 0) {
      int reused = 0;
      for (const QueryKeys* q : sets) reused += before.count(q);
      EXPECT_GE(reused, static_cast<int>(now.lights.size()));
    }
    before = sets;
  }
}

TEST_F(SessionTest, OptionsAreChecked) {
  auto bad = [&](auto change) {
    SessionOptions o;
    change(o);
    auto s = Session::create(w().model, w().scenario, w().map, o);
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(s.status().message());
  };
  EXPECT_NE(bad([](SessionOptions& o) { o.top_p = 0; }).find("top_p"), std::string::npos);
  EXPECT_NE(bad([](SessionOptions& o) { o.temperature = -1; }).find("temperature"), std::string::npos);
  EXPECT_NE(bad([](SessionOptions& o) { o.max_agents = 500; }).find("max_agents"), std::string::npos);
  EXPECT_NE(bad([](SessionOptions& o) { o.controlled_ids = {987654}; }).find("987654"), std::string::npos);
  EXPECT_NE(bad([](SessionOptions& o) { o.mode = static_cast<SessionMode>(7); }).find("mode"), std::string::npos);
  EXPECT_NE(bad([](SessionOptions& o) { o.window_steps = 1; }).find("window_steps"), std::string::npos);
}

TEST(SessionMap, AnEmptyMapIsRefused) {
  auto model = Model::create(init_weights(*model_config_by_name("small"), 1));
  ASSERT_TRUE(model.ok());
  auto map = (*model)->encode_map({});
  EXPECT_EQ(map.status().code(), absl::StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace ss
