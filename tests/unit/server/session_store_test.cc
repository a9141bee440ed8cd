// The session store's scripts and leases against a real redis-server (Debian's, started by the test on a free
// loopback port): two stores with different replica ids stand for two replicas. The URL and replica id rules without
// one.
#include "server/session_store.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "server/session_leases.h"

extern char** environ;

namespace ss::server {
namespace {

TEST(StoreUrl, Parses) {
  auto a = parse_store_url("redis://127.0.0.1:6380/2");
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_EQ(a->host, "127.0.0.1");
  EXPECT_EQ(a->port, 6380);
  EXPECT_EQ(a->db, 2);
  a = parse_store_url("redis://scenestreamer-store:6379");
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_EQ(a->db, 0);
}

TEST(StoreUrl, RefusesWhatIsWrongSayingWhat) {
  const std::pair<const char*, const char*> cases[] = {
      {"127.0.0.1:6379", "not a redis:// URL"},      {"redis://127.0.0.1", "no port"},
      {"redis://:6379", "no host"},                  {"redis://h:70000", "port '70000' is not 1..65535"},
      {"redis://h:x", "port 'x' is not 1..65535"},   {"redis://h:1/16", "database '16' is not 0..15"},
      {"redis://u:p@h:1", "--session_store_password_file"},
  };
  for (const auto& [url, message] : cases) {
    auto a = parse_store_url(url);
    ASSERT_FALSE(a.ok()) << url;
    EXPECT_EQ(a.status().code(), absl::StatusCode::kInvalidArgument) << url;
    EXPECT_NE(std::string(a.status().message()).find(message), std::string::npos) << url << ": " << a.status();
  }
  EXPECT_TRUE(check_replica_id("scenestreamer-0").ok());
  EXPECT_FALSE(check_replica_id("").ok());
  EXPECT_FALSE(check_replica_id("a b").ok());
  EXPECT_FALSE(check_replica_id(std::string(65, 'a')).ok());
}

int free_port() {
  int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(s, reinterpret_cast<sockaddr*>(&a), sizeof(a));
  socklen_t n = sizeof(a);
  getsockname(s, reinterpret_cast<sockaddr*>(&a), &n);
  close(s);
  return ntohs(a.sin_port);
}

class StoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    port_ = free_port();
    const std::string p = std::to_string(port_);
    std::vector<std::string> args = {"redis-server", "--bind", "127.0.0.1", "--port", p, "--save", "",
                                     "--appendonly", "no", "--dir", "/tmp"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    // Its log would bury the test's own output.
    posix_spawn_file_actions_t quiet;
    posix_spawn_file_actions_init(&quiet);
    posix_spawn_file_actions_addopen(&quiet, 1, "/dev/null", O_WRONLY, 0);
    const int spawned = posix_spawnp(&pid_, "redis-server", &quiet, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&quiet);
    ASSERT_EQ(spawned, 0) << "redis-server (Debian's redis-server package) is not on PATH";
    for (int i = 0; i < 200 && !a_; ++i) {
      auto s = SessionStore::connect(options("a"));
      if (s.ok()) a_ = std::move(*s);
      else std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    ASSERT_TRUE(a_) << "redis-server did not answer on port " << port_;
    auto b = SessionStore::connect(options("b"));
    ASSERT_TRUE(b.ok()) << b.status();
    b_ = std::move(*b);
  }
  void TearDown() override {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      waitpid(pid_, nullptr, 0);
    }
  }
  StoreOptions options(const std::string& replica) {
    StoreOptions o;
    o.url = "redis://127.0.0.1:" + std::to_string(port_);
    o.replica_id = replica;
    o.lease_ms = kLeaseMs;
    o.retain_ms = 60000;
    return o;
  }
  static constexpr int kLeaseMs = 400;
  int port_ = 0;
  pid_t pid_ = 0;
  std::unique_ptr<SessionStore> a_, b_;
};

TEST_F(StoreTest, CreateOwnsTheIdAndTheSnapshotIsWrittenOnlyByTheLeaseHolder) {
  auto e = a_->create("s1", "t", "snap-0");
  ASSERT_TRUE(e.ok()) << e.status();
  EXPECT_EQ(b_->create("s1", "t", "x").status().code(), absl::StatusCode::kAlreadyExists);
  ASSERT_TRUE(a_->put("s1", *e, "snap-1", false).ok());
  // B cannot write it, even naming A's epoch: the lease is A's.
  EXPECT_EQ(b_->put("s1", *e, "forged", false).code(), absl::StatusCode::kFailedPrecondition);
  // B asks for it: not taken, A named, and A's renewal now says someone wants it.
  auto t = b_->acquire("s1", "t");
  ASSERT_TRUE(t.ok()) << t.status();
  EXPECT_FALSE(t->taken);
  EXPECT_EQ(t->owner, "a");
  auto r = a_->renew({{"s1", *e}});
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->at("s1"), "want");
  // A hands over: the latest snapshot with the lease released; B takes it with that very snapshot.
  ASSERT_TRUE(a_->put("s1", *e, "snap-2", /*release=*/true).ok());
  t = b_->acquire("s1", "t");
  ASSERT_TRUE(t.ok()) << t.status();
  ASSERT_TRUE(t->taken);
  EXPECT_EQ(t->snapshot, "snap-2");
  EXPECT_GT(t->epoch, *e);
  // A's old epoch writes nothing now, and A's renewal reports the loss naming B.
  auto st = a_->put("s1", *e, "stale", false);
  EXPECT_EQ(st.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(std::string(st.message()).find("lease lost: replica 'b' holds it now"), std::string::npos) << st;
  r = a_->renew({{"s1", *e}});
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->at("s1"), "lost:b");
  ASSERT_TRUE(b_->remove("s1", t->epoch).ok());
  EXPECT_EQ(a_->acquire("s1", "t").status().code(), absl::StatusCode::kNotFound);
}

TEST_F(StoreTest, AnotherTenantFindsNothingAndAsksForNothing) {
  auto e = a_->create("s2", "team-x", "snap");
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(b_->acquire("s2", "team-y").status().code(), absl::StatusCode::kNotFound);
  auto r = a_->renew({{"s2", *e}});
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->at("s2"), "") << "another tenant's call asked for the session";
}

TEST_F(StoreTest, ALapsedLeaseIsTakenByAnotherAndTheOldHolderIsFenced) {
  auto e = a_->create("s3", "t", "snap-a");
  ASSERT_TRUE(e.ok());
  // Not renewed for longer than the lease (A paused or cut off): B takes it. These waits are on wall time because a
  // lease's expiry is the redis-server's own (SET PX runs on its clock); no test clock of ours can advance it.
  std::this_thread::sleep_for(std::chrono::milliseconds(kLeaseMs + 100));
  auto t = b_->acquire("s3", "t");
  ASSERT_TRUE(t.ok());
  ASSERT_TRUE(t->taken);
  ASSERT_TRUE(b_->put("s3", t->epoch, "snap-b", false).ok());
  EXPECT_EQ(a_->put("s3", *e, "snap-a2", false).code(), absl::StatusCode::kFailedPrecondition);
  // A lapsed lease nobody took is still its holder's: renewing it takes it back.
  std::this_thread::sleep_for(std::chrono::milliseconds(kLeaseMs + 100));
  auto r = b_->renew({{"s3", t->epoch}});
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->at("s3"), "");
  EXPECT_TRUE(b_->put("s3", t->epoch, "snap-b2", false).ok());
}

TEST_F(StoreTest, TheKeeperHandsOverWhatAnotherReplicaAsksForAndReportsWhatWasTaken) {
  std::atomic<int> handed{0};
  LeaseKeeper* keeper_a = nullptr;
  LeaseKeeper a(*a_, {[&](const std::string& id) {
                        ++handed;
                        return keeper_a->put(id, "handed", /*release=*/true).ok();
                      },
                      [](const std::string&, const std::string&) {}});
  keeper_a = &a;
  std::string lost_to;
  LeaseKeeper b(*b_, {[](const std::string&) { return false; },
                      [&](const std::string&, const std::string& owner) { lost_to = owner; }});
  ASSERT_TRUE(a.create("s4", "t", "first").ok());
  EXPECT_TRUE(a.hold("s4").ok());
  EXPECT_EQ(b.hold("s4").code(), absl::StatusCode::kNotFound);
  // B waits while A's keeper sees the want at its next renewal and hands the session over.
  auto got = b.acquire("s4", "t", std::chrono::milliseconds(3 * kLeaseMs));
  ASSERT_TRUE(got.ok()) << got.status();
  EXPECT_EQ(*got, "handed");
  EXPECT_EQ(handed.load(), 1);
  EXPECT_EQ(a.hold("s4").code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(b.hold("s4").ok());
  // A held-elsewhere session not handed over in time: UNAVAILABLE naming the holder.
  ASSERT_TRUE(b.create("s5", "t", "x").ok());
  auto refused = a.acquire("s5", "t", std::chrono::milliseconds(100));
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_NE(std::string(refused.status().message()).find("held by replica 'b'"), std::string::npos)
      << refused.status();
}

}  // namespace
}  // namespace ss::server
