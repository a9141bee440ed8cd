// The session manager against the real engine on a tiny configuration (small random weights, the real WOMD
// TFRecords read in place from ../shared): caps, LRU eviction order, the multi-client barrier, ids, status mapping.
// Time is a TestClock where it matters (idle timeouts, tick deadlines, purge intervals): no test sleeps on wall time.
#include "server/session_manager.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <thread>

#include "engine/scenario/read.h"
#include "engine/scenario/womd_proto.h"
#include "server/allocator.h"
#include "server/convert.h"
#include "server/session_id.h"

namespace ss::server {
namespace {

class ManagerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    EngineOptions eo;
    eo.random_config = "small";
    eo.scenario_paths = {SS_DATA_DIR "/womd/tfrecord"};
    auto e = engine_create(eo);
    ASSERT_TRUE(e.ok()) << e.status();
    engine_ = e->release();
    name_ = new std::string(engine_scenarios(*engine_).front().name);
  }
  static void TearDownTestSuite() {
    EngineDeleter()(engine_);
    delete name_;
  }
  // A deadline no test reaches: the test clocks start at the real clock's now and are advanced by seconds at most.
  static TimePoint soon() { return std::chrono::steady_clock::now() + std::chrono::seconds(120); }
  absl::StatusOr<std::string> create(SessionManager& m, const std::string& id, SessionOptions o = {}) {
    std::string out;
    auto t = m.create("", {*name_, ""}, o, 0, id, soon(), &out);
    if (!t.ok()) return t.status();
    return out;
  }
  // A session of the test scenario with two controlled agents (two clients) and a multi-client tick deadline: the
  // first two vehicles of a probe session, whose first-step views go in `two`.
  absl::StatusOr<std::string> create_two_controllers(SessionManager& m, int tick_deadline_ms,
                                                     std::vector<AgentView>& two) {
    std::string probe, id;
    auto first = m.create("", {*name_, ""}, {}, 0, "", soon(), &probe);
    if (!first.ok()) return first.status();
    SessionOptions so;
    for (const AgentView& a : first->view.agents)
      if (a.type == 0 && two.size() < 2) two.push_back(a);
    if (two.size() != 2) return absl::FailedPreconditionError("the test scenario has fewer than two vehicles");
    for (const AgentView& a : two) so.controlled_ids.push_back(static_cast<int32_t>(a.id));
    auto t = m.create("", {*name_, ""}, so, tick_deadline_ms, "", soon(), &id);
    if (!t.ok()) return t.status();
    return id;
  }
  static Engine* engine_;
  static std::string* name_;
  Metrics metrics_;
};
Engine* ManagerTest::engine_ = nullptr;
std::string* ManagerTest::name_ = nullptr;

TEST_F(ManagerTest, TheSessionCapHoldsWithAClearError) {
  ManagerOptions o;
  o.max_sessions = 2;
  o.evict_idle_s = 1000;
  SessionManager m(*engine_, o, metrics_);
  ASSERT_TRUE(create(m, "a").ok());
  ASSERT_TRUE(create(m, "b").ok());
  auto c = create(m, "c");
  EXPECT_EQ(c.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(c.status().message().find("--max_sessions=2"), std::string::npos) << c.status();
  EXPECT_EQ(m.count(), 2);
  auto f = m.fork("a", "", "", soon());
  EXPECT_EQ(f.status().code(), absl::StatusCode::kResourceExhausted);
}

// With one compute thread, a long multi-tick call and one-tick calls on another session take turns: the queue the
// scenestreamer_compute_queued gauge reports holds a call while the other's tick runs, and then empties.
TEST_F(ManagerTest, TheComputeQueueGaugeCountsCallsWaitingForAComputeThread) {
  ManagerOptions o;
  o.compute_threads = 1;
  SessionManager m(*engine_, o, metrics_);
  metrics_.compute_queued = [&] { return m.compute_queued(); };
  ASSERT_TRUE(create(m, "long").ok());
  ASSERT_TRUE(create(m, "short").ok());
  EXPECT_EQ(m.compute_queued(), 0);
  std::atomic<bool> long_done{false};
  std::thread long_call([&] {
    EXPECT_TRUE(m.step("long", "", "", {}, 40, soon()).ok());
    long_done = true;
  });
  std::thread short_call([&] {  // one-tick calls for as long as the long call runs, whichever starts first
    while (!long_done) EXPECT_TRUE(m.step("short", "", "", {}, 1, soon()).ok());
  });
  int most = 0;
  while (!long_done && most < 1) {
    most = std::max(most, m.compute_queued());
    std::this_thread::yield();
  }
  long_call.join();
  short_call.join();
  EXPECT_GE(most, 1);
  EXPECT_LE(most, 2);  // both callers' calls, in the moment before the woken compute thread takes one
  EXPECT_EQ(m.compute_queued(), 0);
  EXPECT_NE(metrics_.render().find("\nscenestreamer_compute_queued 0"), std::string::npos) << metrics_.render();
  metrics_.compute_queued = nullptr;
}

// The reaper gives freed memory back to the kernel once sessions closed, at most every --malloc_trim_s, and not while
// nothing closes (server/allocator.h). The test drives the clock and the reaper's passes.
TEST_F(ManagerTest, TheReaperTrimsMallocAfterSessionsCloseOnly) {
  auto trims = [&] {
    const std::string text = metrics_.render();
    const std::string key = "\nscenestreamer_malloc_trims_total ";
    const size_t at = text.find(key);
    return at == std::string::npos ? -1.0 : std::stod(text.substr(at + key.size()));
  };
  TestClock clock;
  ManagerOptions o;
  o.malloc_trim_interval_s = 0.2;
  o.clock = &clock;
  o.reaper_thread = false;
  SessionManager m(*engine_, o, metrics_);
  ASSERT_TRUE(create(m, "a").ok());
  ASSERT_TRUE(create(m, "b").ok());
  ASSERT_TRUE(m.step("a", "", "", {}, 2, soon()).ok());
  clock.advance(std::chrono::milliseconds(600));
  m.reap();
  EXPECT_EQ(trims(), 0) << "a trim with no session closed";
  ASSERT_TRUE(m.close("a", "").ok());
  ASSERT_TRUE(m.close("b", "").ok());
  m.reap();
  EXPECT_EQ(trims(), 1) << "one purge for both closes";
  clock.advance(std::chrono::milliseconds(600));
  m.reap();
  EXPECT_EQ(trims(), 1) << "trims again with nothing closed since";
  // A close within the interval of the last purge waits for the interval.
  m.reap();
  ASSERT_TRUE(create(m, "c").ok());
  ASSERT_TRUE(m.close("c", "").ok());
  m.reap();  // 600 ms after the last purge: due
  EXPECT_EQ(trims(), 2);
  ASSERT_TRUE(create(m, "d").ok());
  ASSERT_TRUE(m.close("d", "").ok());
  clock.advance(std::chrono::milliseconds(100));
  m.reap();
  EXPECT_EQ(trims(), 2) << "a purge 100 ms after the last one, under --malloc_trim_s=0.2";
  clock.advance(std::chrono::milliseconds(150));
  m.reap();
  EXPECT_EQ(trims(), 3);
}

TEST_F(ManagerTest, EvictionTakesTheLeastRecentlyUsedIdleSession) {
  const auto dir = std::filesystem::temp_directory_path() / "ss-manager-test-snapshots";
  std::filesystem::remove_all(dir);
  ManagerOptions o;
  o.max_sessions = 2;
  o.evict_idle_s = 0;
  o.snapshot_dir = dir.string();
  o.snapshot_interval_s = 0;
  TestClock clock;  // each use at its own time, so the LRU order is not a tie of equal time stamps
  o.clock = &clock;
  o.reaper_thread = false;
  SessionManager m(*engine_, o, metrics_);
  ASSERT_TRUE(create(m, "old").ok());
  clock.advance(std::chrono::milliseconds(1));
  ASSERT_TRUE(create(m, "recent").ok());
  clock.advance(std::chrono::milliseconds(1));
  ASSERT_TRUE(m.step("old", "", "", {}, 1, soon()).ok());  // "old" is now the more recently used
  clock.advance(std::chrono::milliseconds(1));
  ASSERT_TRUE(create(m, "new").ok());
  std::vector<std::string> held;
  for (const SessionInfo& i : m.list("")) held.push_back(i.id);
  EXPECT_EQ(held, (std::vector<std::string>{"new", "old"}));
  EXPECT_TRUE(std::filesystem::exists(dir / "recent.snapshot"));
  // The evicted session comes back on its next call, at the tick it was saved at.
  auto got = m.get("recent", "");
  ASSERT_TRUE(got.ok()) << got.status();
  EXPECT_EQ(got->second.tick, 0);
  ASSERT_TRUE(m.close("recent", "").ok());
  EXPECT_FALSE(std::filesystem::exists(dir / "recent.snapshot"));
  std::filesystem::remove_all(dir);
}

TEST_F(ManagerTest, AMultiClientTickWaitsForEveryControllerAndGivesAllTheSameTick) {
  ManagerOptions o;
  o.evict_idle_s = 1000;
  TestClock clock;  // never advanced: only both poses can make the tick
  o.clock = &clock;
  o.reaper_thread = false;
  SessionManager m(*engine_, o, metrics_);
  std::vector<AgentView> two;
  auto created = create_two_controllers(m, 60000, two);
  ASSERT_TRUE(created.ok()) << created.status();
  const std::string multi = *created;
  std::vector<absl::StatusOr<std::vector<TickView>>> got(2, absl::UnknownError("not run"));
  std::vector<std::thread> clients;
  auto client = [&](int k) {
    const AgentView& a = two[k];
    ControlInput c{a.id, a.state.x + 0.5 * a.state.vx, a.state.y + 0.5 * a.state.vy, a.state.heading, {}};
    got[k] = m.step(multi, "", "", {c}, 1, soon());
  };
  clients.emplace_back(client, 0);
  ASSERT_TRUE(clock.await_waiters(1)) << "the first client's call did not wait for the second";
  EXPECT_EQ(got[0].status().code(), absl::StatusCode::kUnknown) << "returned before the second pose";
  clients.emplace_back(client, 1);  // the late one
  for (auto& c : clients) c.join();
  ASSERT_TRUE(got[0].ok()) << got[0].status();
  ASSERT_TRUE(got[1].ok()) << got[1].status();
  ASSERT_EQ(got[0]->size(), 1u);
  EXPECT_EQ((*got[0])[0].tick, 1);
  EXPECT_EQ((*got[1])[0].tick, 1);
  EXPECT_EQ((*got[0])[0].view.step, (*got[1])[0].view.step);
  // A pose for an agent the session does not control is the wire's mistake: INVALID_ARGUMENT naming it.
  auto bad = m.step(multi, "", "", {ControlInput{123456789, 0, 0, 0, {}}}, 1, soon());
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("123456789"), std::string::npos);
}

// A call that waits is use: under load a call once waited longer than --idle_timeout_s for a compute thread and the
// idle rule closed its session under it. Here the wait is a multi-client tick's for its second controller.
TEST_F(ManagerTest, ASessionWithACallWaitingIsNotIdle) {
  TestClock clock;
  ManagerOptions o;
  o.idle_timeout_s = 0.5;
  o.clock = &clock;
  o.reaper_thread = false;
  SessionManager m(*engine_, o, metrics_);
  std::vector<AgentView> two;
  auto created = create_two_controllers(m, 2500, two);  // the tick waits up to 2.5 s for both
  ASSERT_TRUE(created.ok()) << created.status();
  const std::string multi = *created;
  const AgentView& a = two[0];
  std::atomic<bool> returned{false};
  absl::StatusOr<std::vector<TickView>> got = absl::UnknownError("not run");
  std::thread call([&] {
    got = m.step(multi, "", "", {ControlInput{a.id, a.state.x, a.state.y, a.state.heading, 0.0}}, 1, soon());
    returned = true;
  });
  ASSERT_TRUE(clock.await_waiters(1));
  clock.advance(std::chrono::seconds(1));
  ASSERT_TRUE(clock.await_waits(clock.waits() + 1));  // the call saw 1 s pass and waits on
  EXPECT_FALSE(returned) << "the tick ran before its deadline with one of two poses";
  m.reap();
  EXPECT_EQ(m.count(), 1) << "the probe session (idle 1 s) is closed, the one with a waiting call is not";
  clock.advance(std::chrono::milliseconds(1500));  // the tick deadline
  call.join();
  ASSERT_TRUE(got.ok()) << got.status();  // made at the tick deadline with one controller's pose, not closed
  EXPECT_EQ((*got)[0].tick, 1);
  EXPECT_TRUE(m.get(multi, "").ok());
  m.reap();
  EXPECT_EQ(m.count(), 1) << "just used";
  // Unused afterwards (count() does not use a session), it is closed by the same rule.
  clock.advance(std::chrono::milliseconds(600));
  m.reap();
  EXPECT_EQ(m.count(), 0);
}

TEST_F(ManagerTest, AnotherTenantsSessionIsAnsweredAsAnUnknownOne) {
  ManagerOptions o;
  o.evict_idle_s = 1000;
  SessionManager m(*engine_, o, metrics_);
  std::string id;
  ASSERT_TRUE(m.create("alice", {*name_, ""}, {}, 0, "hers", soon(), &id).ok());
  const auto unknown = m.get("never-was", "bob").status();
  ASSERT_EQ(unknown.code(), absl::StatusCode::kNotFound);
  auto same = [&](const absl::Status& st) {
    EXPECT_EQ(st.code(), absl::StatusCode::kNotFound) << st;
    // The same words as for an unknown id, with only the id itself differing.
    std::string msg(st.message());
    msg.replace(msg.find("'hers'"), 6, "'never-was'");
    EXPECT_EQ(msg, unknown.message());
  };
  same(m.get("hers", "bob").status());
  same(m.step("hers", "bob", "", {}, 1, soon()).status());
  InjectRequest one;
  one.count = 1;
  same(m.inject("hers", "bob", one, soon()).status());
  same(m.state_force("hers", "bob", "", {}));
  same(m.fork("hers", "bob", "", soon()).status());
  same(m.join("hers", "bob", {1}, "").status());
  same(m.close("hers", "bob"));
  EXPECT_TRUE(m.list("bob").empty());
  ASSERT_EQ(m.list("alice").size(), 1u);
  EXPECT_TRUE(m.step("hers", "alice", "", {}, 1, soon()).ok());  // untouched by bob's calls
  auto f = m.fork("hers", "alice", "", soon());
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(m.get(*f, "bob").status().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(m.close("hers", "alice").ok());
}

TEST_F(ManagerTest, OnlyAnAgentsControllerSendsItsPoses) {
  ManagerOptions o;
  o.evict_idle_s = 1000;
  SessionManager m(*engine_, o, metrics_);
  std::vector<AgentView> two;
  auto created = create_two_controllers(m, 60000, two);
  ASSERT_TRUE(created.ok()) << created.status();
  const std::string id = *created;
  auto a = m.join(id, "", {two[0].id}, "");
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_EQ(a->credential.size(), 32u);
  EXPECT_EQ(a->agents, std::vector<int64_t>{two[0].id});
  // Claimed once: a second client cannot take it.
  EXPECT_EQ(m.join(id, "", {two[0].id}, "").status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_EQ(m.join(id, "", {987654}, "").status().code(), absl::StatusCode::kInvalidArgument);
  auto b = m.join(id, "", {two[1].id}, "");
  ASSERT_TRUE(b.ok()) << b.status();
  auto pose = [](const AgentView& v) {
    return ControlInput{v.id, v.state.x + 0.5 * v.state.vx, v.state.y + 0.5 * v.state.vy, v.state.heading, {}};
  };
  // B (or anyone without A's credential) sending A's agent's pose: PERMISSION_DENIED naming the agent.
  for (const std::string& cred : {std::string(), b->credential}) {
    auto st = m.step(id, "", cred, {pose(two[0])}, 1, soon()).status();
    EXPECT_EQ(st.code(), absl::StatusCode::kPermissionDenied) << st;
    EXPECT_NE(st.message().find(std::to_string(two[0].id)), std::string::npos) << st;
    EXPECT_NE(st.message().find("controller"), std::string::npos) << st;
  }
  EXPECT_EQ(m.step(id, "", "forged", {}, 1, soon()).status().code(), absl::StatusCode::kPermissionDenied);
  StateForceRequest force;
  force.agents.push_back({two[0].id, two[0].state});
  EXPECT_EQ(m.state_force(id, "", b->credential, force).code(), absl::StatusCode::kPermissionDenied);
  // Each controller's own pose goes through, and the tick advances with both.
  std::vector<absl::StatusOr<std::vector<TickView>>> got(2, absl::UnknownError("not run"));
  std::thread tb([&] { got[1] = m.step(id, "", b->credential, {pose(two[1])}, 1, soon()); });
  got[0] = m.step(id, "", a->credential, {pose(two[0])}, 1, soon());
  tb.join();
  ASSERT_TRUE(got[0].ok()) << got[0].status();
  ASSERT_TRUE(got[1].ok()) << got[1].status();
  EXPECT_EQ((*got[0])[0].tick, 1);
  EXPECT_EQ((*got[1])[0].tick, 1);
}

// Once a tenant's creates evicted another tenant's idle session, and without a snapshot directory dropped it: the
// victim's next call got the NOT_FOUND of an id that never was, and the refusal the other tenant got named the
// server-wide counts.
TEST_F(ManagerTest, OneTenantNeverDropsAnothersSessionNorLearnsItsCounts) {
  ManagerOptions o;
  o.max_sessions = 3;
  o.evict_idle_s = 0;  // every session is idle enough to be evicted at once
  SessionManager m(*engine_, o, metrics_);
  std::string id;
  ASSERT_TRUE(m.create("bob", {*name_, ""}, {}, 0, "bobs", soon(), &id).ok());
  ASSERT_TRUE(m.create("alice", {*name_, ""}, {}, 0, "a1", soon(), &id).ok());
  ASSERT_TRUE(m.create("alice", {*name_, ""}, {}, 0, "a2", soon(), &id).ok());
  auto third = m.create("alice", {*name_, ""}, {}, 0, "a3", soon(), &id);
  EXPECT_EQ(third.status().code(), absl::StatusCode::kResourceExhausted) << third.status();
  const std::string msg(third.status().message());
  EXPECT_EQ(msg.find("3 sessions"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("bytes"), std::string::npos) << msg;
  auto bobs = m.get("bobs", "bob");
  EXPECT_TRUE(bobs.ok()) << bobs.status();
  EXPECT_TRUE(m.get("a1", "alice").ok());
  EXPECT_TRUE(m.get("a2", "alice").ok());
}

// Per-tenant quotas: a tenant at its own cap is refused with its own figures, and the other tenants still create.
TEST_F(ManagerTest, ATenantQuotaHoldsAndLeavesRoomForTheOthers) {
  ManagerOptions o;
  o.max_sessions = 8;
  o.tenant_max_sessions = 2;
  o.evict_idle_s = 1000;
  SessionManager m(*engine_, o, metrics_);
  std::string id;
  ASSERT_TRUE(m.create("alice", {*name_, ""}, {}, 0, "a1", soon(), &id).ok());
  ASSERT_TRUE(m.create("alice", {*name_, ""}, {}, 0, "a2", soon(), &id).ok());
  auto third = m.create("alice", {*name_, ""}, {}, 0, "a3", soon(), &id);
  EXPECT_EQ(third.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(third.status().message().find("--tenant_max_sessions=2"), std::string::npos) << third.status();
  EXPECT_EQ(m.fork("a1", "alice", "", soon()).status().code(), absl::StatusCode::kResourceExhausted);
  ASSERT_TRUE(m.create("bob", {*name_, ""}, {}, 0, "b1", soon(), &id).ok());
  ASSERT_TRUE(m.create("bob", {*name_, ""}, {}, 0, "b2", soon(), &id).ok());
  ASSERT_TRUE(m.close("a1", "alice").ok());
  EXPECT_TRUE(m.create("alice", {*name_, ""}, {}, 0, "a3", soon(), &id).ok());
}

// Once CloseSession let a StepScene of many ticks compute to its end and return OK.
TEST_F(ManagerTest, CloseStopsALongStepOfTheSession) {
  ManagerOptions o;
  o.evict_idle_s = 1000;
  SessionManager m(*engine_, o, metrics_);
  SessionOptions so;
  so.control_sdc = false;  // no controlled agent: num_ticks > 1 is allowed
  ASSERT_TRUE(create(m, "long", so).ok());
  absl::StatusOr<std::vector<TickView>> got = absl::UnknownError("not run");
  std::thread t([&] { got = m.step("long", "", "", {}, 1000, soon()); });
  while (true) {
    auto g = m.get("long", "");
    if (!g.ok() || g->second.tick >= 2) break;
    std::this_thread::yield();
  }
  ASSERT_TRUE(m.close("long", "").ok());
  t.join();
  EXPECT_EQ(got.status().code(), absl::StatusCode::kAborted) << got.status();
  EXPECT_NE(got.status().message().find("closed"), std::string::npos) << got.status();
}

// What a session on a client-sent scenario holds is what it counts (--max_cache_mb): once 12 sessions on a 60 MB
// scenario counted 848 MB with 1,670 MB in use. The scenario here: a real one with its map features copied eight
// times over (ids and places shifted) and laser data, so the scenario's own parts dominate.
TEST_F(ManagerTest, ASessionOnAClientSentScenarioCountsWhatItHolds) {
  auto all = read_scenarios(SS_DATA_DIR "/womd/tfrecord");
  ASSERT_TRUE(all.ok()) << all.status();
  Scenario s = all->front();
  const size_t features = s.map_features.size();
  int64_t next_id = 0;
  for (const MapFeature& f : s.map_features) next_id = std::max(next_id, f.id + 1);
  for (int copy = 1; copy < 8; ++copy)
    for (size_t i = 0; i < features; ++i) {
      MapFeature f = s.map_features[i];
      f.id = next_id++;
      for (MapPoint& p : f.points) p.x += 2000.0 * copy;
      f.lane = {};
      if (f.kind == MapFeatureKind::lane) f.kind = MapFeatureKind::road_line;
      f.stop_sign_lanes.clear();
      s.map_features.push_back(f);
    }
  s.laser_data.assign(5, std::string(1 << 20, 'l'));
  SessionSource source;
  source.womd_bytes = scenario_to_womd_bytes(s);
  ManagerOptions o;
  o.evict_idle_s = 1000;
  o.compute_threads = 1;
  SessionManager m(*engine_, o, metrics_);
  ASSERT_TRUE(create(m, "warm-up").ok());  // the compute thread's buffers, the engine's first-use state
  ASSERT_TRUE(m.step("warm-up", "", "", {}, 1, soon()).ok());
  const uint64_t before = allocator_stats().in_use;
  std::string id;
  auto t = m.create("", source, {}, 0, "big", soon(), &id);
  ASSERT_TRUE(t.ok()) << t.status();
  t = absl::UnknownError("dropped");  // the first tick's copy is the caller's, not the session's
  const uint64_t held = allocator_stats().in_use - before;
  const uint64_t counted = m.get("big", "")->first.memory_bytes;
  std::printf("a session on a %zu-byte client-sent scenario holds %.1f MiB, counts %.1f MiB\n",
              source.womd_bytes.size(), held / 1048576.0, counted / 1048576.0);
  EXPECT_GT(held, uint64_t{8} << 20);
  EXPECT_GE(counted, held * 9 / 10) << "held " << held << ", counted " << counted;
  EXPECT_LE(counted, held * 11 / 10) << "held " << held << ", counted " << counted;
}

TEST(SessionId, TheRuleAndShortEchoes) {
  EXPECT_TRUE(check_session_id("a-b_c.9").ok());
  EXPECT_EQ(check_session_id("").code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(check_session_id("../escaped").code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(check_session_id(".hidden").code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(check_session_id(std::string(129, 'a')).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(random_session_id().size(), 32u);
  EXPECT_NE(random_session_id(), random_session_id());
  const std::string echo = echo_id(std::string(8000, 'x'));
  EXPECT_LT(echo.size(), 100u);
  EXPECT_NE(echo.find("8000 bytes"), std::string::npos);
}

TEST(StatusMapping, EveryEngineCodeKeepsItsGrpcCodeAndMessage) {
  for (auto code : {absl::StatusCode::kInvalidArgument, absl::StatusCode::kNotFound, absl::StatusCode::kFailedPrecondition,
                    absl::StatusCode::kResourceExhausted, absl::StatusCode::kUnavailable, absl::StatusCode::kAborted,
                    absl::StatusCode::kDeadlineExceeded, absl::StatusCode::kDataLoss, absl::StatusCode::kAlreadyExists}) {
    const ::grpc::Status g = to_grpc(absl::Status(code, "what went wrong"));
    EXPECT_EQ(static_cast<int>(g.error_code()), static_cast<int>(code));
    EXPECT_EQ(g.error_message(), "what went wrong");
  }
  EXPECT_TRUE(to_grpc(absl::OkStatus()).ok());
}

}  // namespace
}  // namespace ss::server
