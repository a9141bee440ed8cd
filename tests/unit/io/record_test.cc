// The one framed record (engine/io/record.h): a record reads back as written; a cut or a flipped bit anywhere is
// DATA_LOSS; another version of the format is FAILED_PRECONDITION naming both; bytes of another kind are
// INVALID_ARGUMENT; the layouts before the framing (the magic first, an FNV-1a hash before or after the message) are
// still read, and their hash still checked.
#include "engine/io/record.h"

#include <gtest/gtest.h>

#include "engine/base/rng.h"
#include "engine/scenario/tfrecord.h"

namespace ss {
namespace {

constexpr RecordFormat kState{"TESTSTA3", 1, "test state", "engine", RecordFormat::Earlier::hash_then_message};
constexpr RecordFormat kFile{"TESTFI07", 2, "test file", "server", RecordFormat::Earlier::message_then_hash};

std::string le64(uint64_t v) {
  std::string out;
  for (int i = 0; i < 8; ++i) out += static_cast<char>((v >> (8 * i)) & 0xff);
  return out;
}

TEST(Record, ReadsBackWhatWasWrittenAndIsATfRecord) {
  const std::string message("a message\0with a zero byte", 26);
  const std::string bytes = record_write(kState, message);
  auto got = record_read(kState, bytes);
  ASSERT_TRUE(got.ok()) << got.status();
  EXPECT_EQ(*got, message);
  auto records = parse_tfrecords(bytes, "record");  // any TFRecord reader opens it
  ASSERT_TRUE(records.ok()) << records.status();
  ASSERT_EQ(records->size(), 1u);
  EXPECT_EQ(records->front(), "TESTSTA3" + message);
  EXPECT_EQ(*record_read(kState, record_write(kState, "")), "");
}

TEST(Record, EveryCutAndEveryFlippedBitIsRefused) {
  const std::string bytes = record_write(kFile, "the payload of a test record");
  for (size_t n = 0; n < bytes.size(); ++n) EXPECT_FALSE(record_read(kFile, bytes.substr(0, n)).ok()) << "cut at " << n;
  for (size_t n = 12; n < bytes.size(); ++n)
    EXPECT_EQ(record_read(kFile, bytes.substr(0, n)).status().code(), absl::StatusCode::kDataLoss) << n;
  for (size_t i = 0; i < bytes.size(); ++i)
    for (int bit = 0; bit < 8; ++bit) {
      std::string b = bytes;
      b[i] = static_cast<char>(b[i] ^ (1 << bit));
      auto r = record_read(kFile, b);
      ASSERT_FALSE(r.ok()) << "bit " << bit << " of byte " << i;
      EXPECT_EQ(r.status().code(), absl::StatusCode::kDataLoss) << "byte " << i << ": " << r.status();
      EXPECT_NE(r.status().message().find("checksum mismatch"), std::string::npos) << r.status();
    }
}

TEST(Record, AnotherVersionIsRefusedNamingBoth) {
  constexpr RecordFormat older{"TESTSTA2", 1, "test state", "engine"};
  auto r = record_read(kState, record_write(older, "m"));
  EXPECT_EQ(r.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("format TESTSTA2 is not this engine's TESTSTA3"), std::string::npos) << r.status();
  EXPECT_NE(r.status().message().find("version 2 is not this engine's version 3"), std::string::npos) << r.status();
  // The same in the layout before the framing.
  auto e = record_read(kFile, "TESTFI01" + std::string("old") + le64(fnv1a64("TESTFI01old")));
  EXPECT_EQ(e.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(e.status().message().find("format TESTFI01 is not this server's TESTFI07"), std::string::npos) << e.status();
}

TEST(Record, BytesOfAnotherKindAreNotARecordOfTheFormat) {
  EXPECT_EQ(record_read(kState, "nonsense").status().code(), absl::StatusCode::kInvalidArgument);
  auto r = record_read(kState, record_write(kFile, "m"));
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("no TESTSTA magic"), std::string::npos) << r.status();
  auto two = record_read(kState, record_write(kState, "a") + record_write(kState, "b"));
  EXPECT_EQ(two.status().code(), absl::StatusCode::kDataLoss);
}

TEST(Record, TheEarlierLayoutsAreReadAndTheirHashChecked) {
  // The state's: magic, the FNV-1a hash of the message, the message.
  const std::string state = "TESTSTA3" + le64(fnv1a64("old state")) + "old state";
  auto s = record_read(kState, state);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(*s, "old state");
  // The file's: magic, the message, the FNV-1a hash of both.
  const std::string file = "TESTFI07old file" + le64(fnv1a64("TESTFI07old file"));
  auto f = record_read(kFile, file);
  ASSERT_TRUE(f.ok()) << f.status();
  EXPECT_EQ(*f, "old file");
  for (const auto& [format, bytes] : {std::pair{kState, state}, std::pair{kFile, file}}) {
    for (size_t i = 8; i < bytes.size(); ++i) {
      std::string b = bytes;
      b[i] = static_cast<char>(b[i] ^ 0x10);
      EXPECT_EQ(record_read(format, b).status().code(), absl::StatusCode::kDataLoss) << format.what << " byte " << i;
    }
    EXPECT_EQ(record_read(format, bytes.substr(0, 12)).status().code(), absl::StatusCode::kDataLoss);
  }
}

}  // namespace
}  // namespace ss
