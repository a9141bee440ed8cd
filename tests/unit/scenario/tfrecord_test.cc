#include "engine/scenario/tfrecord.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

namespace ss {
namespace {

using ::testing::HasSubstr;

// Unique per test process: ctest runs each test in its own process, several at once, in one temp directory.
std::string temp_path(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / (std::to_string(::getpid()) + "_" + name)).string();
}

void write_raw(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

TEST(Crc32c, KnownVectors) {
  EXPECT_EQ(crc32c(""), 0u);
  EXPECT_EQ(crc32c("123456789"), 0xE3069283u);
  EXPECT_EQ(crc32c("a"), 0xC1D04330u);
  // RFC 3720 (iSCSI) B.4: 32 bytes of zeros, of 0xFF, ascending and descending.
  EXPECT_EQ(crc32c(std::string(32, '\0')), 0x8A9136AAu);
  EXPECT_EQ(crc32c(std::string(32, '\xFF')), 0x62A8AB43u);
  std::string up, down;
  for (int i = 0; i < 32; ++i) {
    up += static_cast<char>(i);
    down += static_cast<char>(31 - i);
  }
  EXPECT_EQ(crc32c(up), 0x46DD794Eu);
  EXPECT_EQ(crc32c(down), 0x113FDB5Cu);
}

TEST(Crc32c, ExtendMatchesWhole) {
  std::string data;
  for (int i = 0; i < 1000; ++i) data += static_cast<char>(i * 7 + 3);
  for (size_t cut : {0, 1, 7, 8, 9, 500, 999, 1000})
    EXPECT_EQ(crc32c_extend(crc32c(data.substr(0, cut)), data.substr(cut)), crc32c(data)) << cut;
}

TEST(Crc32c, MaskRoundTrip) {
  for (uint32_t c : {0u, 1u, 0xE3069283u, 0xFFFFFFFFu}) EXPECT_EQ(unmask_crc(mask_crc(c)), c);
  EXPECT_EQ(mask_crc(0), 0xA282EAD8u);
}

TEST(TfRecord, FrameLayout) {
  const std::string f = tfrecord_frame("abc");
  ASSERT_EQ(f.size(), 12u + 3 + 4);
  EXPECT_EQ(f.substr(0, 8), std::string("\x03\0\0\0\0\0\0\0", 8));
  EXPECT_EQ(f.substr(12, 3), "abc");
}

TEST(TfRecord, RoundTripInMemory) {
  const std::vector<std::string> records = {"", "x", std::string(100000, 'q'), std::string("\0\1\2", 3)};
  std::string bytes;
  for (const auto& r : records) bytes += tfrecord_frame(r);
  auto parsed = parse_tfrecords(bytes, "mem");
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(*parsed, records);
  auto none = parse_tfrecords("", "mem");
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
}

TEST(TfRecord, RoundTripThroughFile) {
  const std::string path = temp_path("roundtrip.tfrecord");
  const std::vector<std::string> records = {"first", "", "third record"};
  ASSERT_TRUE(write_tfrecord_file(path, records).ok());
  auto read = read_tfrecord_file(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(*read, records);

  auto reader = TfRecordReader::open(path);
  ASSERT_TRUE(reader.ok());
  std::string r;
  int n = 0;
  while (true) {
    auto more = reader->next(&r);
    ASSERT_TRUE(more.ok()) << more.status();
    if (!*more) break;
    EXPECT_EQ(r, records[n++]);
  }
  EXPECT_EQ(n, 3);
  // No temporary file is left next to the target.
  for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(path).parent_path()))
    EXPECT_EQ(e.path().filename().string().find("roundtrip.tfrecord.tmp"), std::string::npos) << e.path();
}

TEST(TfRecord, MissingFileIsNotFound) {
  auto r = read_tfrecord_file(temp_path("does-not-exist.tfrecord"));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(std::string(r.status().message()), HasSubstr("does-not-exist.tfrecord"));
}

TEST(TfRecord, WriteIntoMissingDirectoryFails) {
  auto st = write_tfrecord_file(temp_path("no/such/dir/x.tfrecord"), {"a"});
  EXPECT_EQ(st.code(), absl::StatusCode::kNotFound) << st;
}

// Each corruption is checked both in memory and through the file reader: same message, record index and offset.
void expect_error(const std::string& bytes, const std::string& what, const std::string& record) {
  auto mem = parse_tfrecords(bytes, "t.tfrecord");
  ASSERT_FALSE(mem.ok()) << what;
  EXPECT_EQ(mem.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(mem.status().message()), HasSubstr(what));
  EXPECT_THAT(std::string(mem.status().message()), HasSubstr(record));
  EXPECT_THAT(std::string(mem.status().message()), HasSubstr("t.tfrecord"));

  const std::string path = temp_path("corrupt.tfrecord");
  write_raw(path, bytes);
  auto file = read_tfrecord_file(path);
  ASSERT_FALSE(file.ok()) << what;
  EXPECT_EQ(file.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(std::string(file.status().message()), HasSubstr(what));
  EXPECT_THAT(std::string(file.status().message()), HasSubstr(record));
  EXPECT_THAT(std::string(file.status().message()), HasSubstr(path));
}

class TfRecordCorruption : public ::testing::Test {
 protected:
  // Two good records: the second starts at byte 12 + 5 + 4 = 21, and the file is 43 bytes.
  std::string good = tfrecord_frame("hello") + tfrecord_frame("world!");
};

TEST_F(TfRecordCorruption, TruncatedHeader) {
  expect_error(good.substr(0, 21 + 5), "truncated header: 5 of 12 bytes", "record 1 (byte offset 21)");
}

TEST_F(TfRecordCorruption, TruncatedData) {
  expect_error(good.substr(0, 21 + 12 + 3), "truncated data: length 6 but only 3 bytes", "record 1 (byte offset 21)");
}

TEST_F(TfRecordCorruption, TruncatedFooter) {
  expect_error(good.substr(0, good.size() - 1), "truncated footer: 3 of 4 bytes", "record 1 (byte offset 21)");
}

TEST_F(TfRecordCorruption, LengthCrcMismatch) {
  std::string bad = good;
  bad[21 + 9] ^= 0x40;  // the stored length CRC
  expect_error(bad, "length CRC mismatch", "record 1 (byte offset 21)");
  bad = good;
  bad[21] = 7;  // the length itself: caught by the CRC, not reported as truncation
  expect_error(bad, "length CRC mismatch", "record 1 (byte offset 21)");
}

TEST_F(TfRecordCorruption, DataCrcMismatch) {
  std::string bad = good;
  bad[12] ^= 1;  // first byte of record 0's data
  expect_error(bad, "data CRC mismatch", "record 0 (byte offset 0)");
  bad = good;
  bad[good.size() - 1] ^= 1;  // record 1's stored data CRC
  expect_error(bad, "data CRC mismatch", "record 1 (byte offset 21)");
}

TEST_F(TfRecordCorruption, AbsurdLengthIsRejectedBeforeAllocating) {
  // A well-formed header (valid CRC) announcing 2^40 bytes, followed by nothing.
  std::string header(8, '\0');
  header[5] = 1;
  const uint32_t crc = mask_crc(crc32c(header));
  for (int i = 0; i < 4; ++i) header += static_cast<char>((crc >> (8 * i)) & 0xFF);
  expect_error(good + header, "exceeds the limit", "record 2 (byte offset 43)");
  // Just under the limit but past the end of the file.
  std::string h2(8, '\0');
  h2[3] = 0x20;  // 512 MiB
  const uint32_t crc2 = mask_crc(crc32c(h2));
  for (int i = 0; i < 4; ++i) h2 += static_cast<char>((crc2 >> (8 * i)) & 0xFF);
  expect_error(h2, "truncated data: length 536870912 but only 0 bytes", "record 0 (byte offset 0)");
}

TEST_F(TfRecordCorruption, ReaderStopsAtTheBadRecord) {
  std::string bad = good;
  bad[good.size() - 1] ^= 1;
  const std::string path = temp_path("stops.tfrecord");
  write_raw(path, bad);
  auto reader = TfRecordReader::open(path);
  ASSERT_TRUE(reader.ok());
  std::string r;
  auto first = reader->next(&r);
  ASSERT_TRUE(first.ok() && *first);
  EXPECT_EQ(r, "hello");
  EXPECT_FALSE(reader->next(&r).ok());
  EXPECT_EQ(reader->records_read(), 1);
}

}  // namespace
}  // namespace ss
