// Snapshot files (server/snapshot.h): written and read back; a file in the layout before the one framed record
// (magic, message, FNV-1a hash), with an engine state in its own earlier layout, still restores; a flipped bit, a cut,
// another file and another version are refused, each with its own code and a message naming the file.
#include "server/snapshot.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "engine/base/rng.h"
#include "engine/io/file_io.h"
#include "state/snapshot.pb.h"

namespace ss::server {
namespace {

std::string le64(uint64_t v) {
  std::string out;
  for (int i = 0; i < 8; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
  return out;
}

class SnapshotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("ss-snapshot-test-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& id) const { return (dir_ / (id + ".snapshot")).string(); }
  std::string read(const std::string& id) const { return *file_read_all(path(id)); }
  void write(const std::string& id, const std::string& bytes) const {
    std::ofstream(path(id), std::ios::binary) << bytes;
  }
  static Snapshot sample(const std::string& id) {
    Snapshot s;
    s.session_id = id;
    s.tenant = "alice";
    s.controllers = {{7, "credential"}};
    s.source.scenario_name = "a scenario";
    s.tick_deadline_ms = 1500;
    s.session_bytes = "the engine's state";
    return s;
  }
  std::filesystem::path dir_;
};

TEST_F(SnapshotTest, ReadsBackWhatWasWritten) {
  ASSERT_TRUE(write_snapshot(dir_.string(), sample("s1")).ok());
  auto got = read_snapshot(dir_.string(), "s1");
  ASSERT_TRUE(got.ok()) << got.status();
  EXPECT_EQ(got->tenant, "alice");
  EXPECT_EQ(got->controllers, (std::vector<std::pair<int64_t, std::string>>{{7, "credential"}}));
  EXPECT_EQ(got->source.scenario_name, "a scenario");
  EXPECT_EQ(got->tick_deadline_ms, 1500);
  EXPECT_EQ(got->session_bytes, "the engine's state");
  EXPECT_EQ(list_snapshots(dir_.string()), std::vector<std::string>{"s1"});
}

TEST_F(SnapshotTest, AFlippedBitOrACutIsDataLossNamingTheFile) {
  ASSERT_TRUE(write_snapshot(dir_.string(), sample("s2")).ok());
  const std::string bytes = read("s2");
  for (size_t i = 0; i < bytes.size(); i += 3) {
    std::string b = bytes;
    b[i] = static_cast<char>(b[i] ^ 0x20);
    write("s2", b);
    auto r = read_snapshot(dir_.string(), "s2");
    ASSERT_EQ(r.status().code(), absl::StatusCode::kDataLoss) << "byte " << i << ": " << r.status();
    EXPECT_NE(r.status().message().find("checksum mismatch"), std::string::npos) << r.status();
    EXPECT_NE(r.status().message().find(path("s2")), std::string::npos) << r.status();
  }
  write("s2", bytes.substr(0, bytes.size() - 1));
  EXPECT_EQ(read_snapshot(dir_.string(), "s2").status().code(), absl::StatusCode::kDataLoss);
  std::filesystem::create_directories(dir_);
  write("s3", "not a snapshot at all, just some text");
  EXPECT_EQ(read_snapshot(dir_.string(), "s3").status().code(), absl::StatusCode::kDataLoss);
}

TEST_F(SnapshotTest, AnotherVersionIsRefusedNamingBoth) {
  ASSERT_TRUE(write_snapshot(dir_.string(), sample("s4")).ok());
  auto message = record_read({"SSSNAP05", 2, "snapshot", "server"}, read("s4"));
  ASSERT_TRUE(message.ok()) << message.status();
  write("s4", record_write({"SSSNAP04", 2, "snapshot", "server"}, *message));
  auto r = read_snapshot(dir_.string(), "s4");
  EXPECT_EQ(r.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("format SSSNAP04 is not this server's SSSNAP05"), std::string::npos)
      << r.status();
}

// A file an earlier server wrote: its own layout (magic, message, hash of both) around an engine state in the
// engine's earlier layout (magic, hash of the message, message). It restores, and continues like the session saved.
TEST_F(SnapshotTest, AFileInTheLayoutBeforeTheFramingRestores) {
  EngineOptions eo;
  eo.random_config = "small";
  eo.scenario_paths = {SS_DATA_DIR "/womd/tfrecord"};
  auto engine = engine_create(eo);
  ASSERT_TRUE(engine.ok()) << engine.status();
  const SessionSource source{engine_scenarios(**engine).front().name, ""};
  auto session = session_create(**engine, source, {});
  ASSERT_TRUE(session.ok()) << session.status();
  ASSERT_TRUE(session_tick(**session, {}).ok());
  auto state = record_read({"SSSESSN3", 1, "session snapshot", "engine"}, session_save(**session));
  ASSERT_TRUE(state.ok()) << state.status();
  state::Snapshot m;
  m.set_session_id("old");
  m.set_tenant("bob");
  m.set_scenario_name(source.scenario_name);
  m.set_tick_deadline_ms(2000);
  m.set_session_state("SSSESSN3" + le64(fnv1a64(*state)) + *state);
  const std::string file = "SSSNAP05" + m.SerializeAsString();
  std::filesystem::create_directories(dir_);
  write("old", file + le64(fnv1a64(file)));
  auto snap = read_snapshot(dir_.string(), "old");
  ASSERT_TRUE(snap.ok()) << snap.status();
  EXPECT_EQ(snap->tenant, "bob");
  auto restored = session_restore(**engine, snap->source, snap->session_bytes);
  ASSERT_TRUE(restored.ok()) << restored.status();
  EXPECT_EQ(session_save(**restored), session_save(**session));
  auto a = session_tick(**restored, {});
  auto b = session_tick(**session, {});
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(session_save(**restored), session_save(**session));
}

}  // namespace
}  // namespace ss::server
