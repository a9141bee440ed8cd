#include "engine/io/file_io.h"

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace ss {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A fresh, empty directory per test, so that listing it shows exactly what the test left behind.
std::string fresh_dir() {
  const fs::path dir = fs::path(::testing::TempDir()) / "file_io_test" /
                       ::testing::UnitTest::GetInstance()->current_test_info()->name();
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::vector<std::string> names_in(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

std::string message(const absl::Status& st) { return std::string(st.message()); }

TEST(FileIo, RoundTrip) {
  const std::string dir = fresh_dir();
  const std::string path = dir + "/data.bin";
  const char raw[] = "binary\0with\xff nul and high bytes\n";
  const std::string bytes(raw, sizeof raw - 1);
  ASSERT_TRUE(file_write_atomically(path, bytes).ok());
  auto back = file_read_all(path);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(*back, bytes);

  ASSERT_TRUE(file_write_atomically(path, "").ok());
  back = file_read_all(path);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(*back, "");
}

TEST(FileIo, OverwriteReplacesTheContent) {
  const std::string dir = fresh_dir();
  const std::string path = dir + "/data.txt";
  ASSERT_TRUE(file_write_atomically(path, "old content, longer than the new").ok());
  ASSERT_TRUE(file_write_atomically(path, "new").ok());
  EXPECT_EQ(*file_read_all(path), "new");
  // Success leaves no temporary file behind.
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"data.txt"});
}

TEST(FileIo, ReadingAMissingFileIsNotFoundNamingThePath) {
  const std::string path = fresh_dir() + "/no-such-file.bin";
  auto r = file_read_all(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(message(r.status()), HasSubstr(path));
  EXPECT_THAT(message(r.status()), HasSubstr("cannot open"));
}

TEST(FileIo, ReadingADirectoryIsRefused) {
  const std::string dir = fresh_dir();
  auto r = file_read_all(dir);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(message(r.status()), HasSubstr(dir));
  EXPECT_THAT(message(r.status()), HasSubstr("not a regular file"));
}

TEST(FileIo, WritingIntoAMissingDirectoryIsNotFoundNamingThePath) {
  const std::string dir = fresh_dir();
  const std::string path = dir + "/no/such/dir/x.bin";
  const absl::Status st = file_write_atomically(path, "x");
  EXPECT_EQ(st.code(), absl::StatusCode::kNotFound) << st;
  EXPECT_THAT(message(st), HasSubstr(path));
  EXPECT_THAT(message(st), HasSubstr("cannot create a temporary file"));
  EXPECT_TRUE(names_in(dir).empty());
}

TEST(FileIo, FailedRenameRemovesTheTemporaryFile) {
  // A non-empty directory cannot be renamed over: everything up to the rename succeeds, then it fails.
  const std::string dir = fresh_dir();
  const std::string path = dir + "/target";
  fs::create_directory(path);
  std::ofstream(path + "/inside") << "x";
  const absl::Status st = file_write_atomically(path, "bytes");
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(message(st), HasSubstr("cannot rename to " + path));
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"target"});
  EXPECT_EQ(names_in(path), std::vector<std::string>{"inside"});
}

TEST(FileIo, FailedWriteKeepsTheOldContent) {
  // A file-size limit makes write() fail part way (EFBIG), even for root. SIGXFSZ would otherwise kill the process.
  const std::string dir = fresh_dir();
  const std::string path = dir + "/data.txt";
  ASSERT_TRUE(file_write_atomically(path, "old").ok());
  rlimit saved;
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &saved), 0);
  rlimit small = saved;
  small.rlim_cur = 1024;
  auto* old_handler = std::signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  const absl::Status st = file_write_atomically(path, std::string(8192, 'n'));
  ::setrlimit(RLIMIT_FSIZE, &saved);
  std::signal(SIGXFSZ, old_handler);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(message(st), HasSubstr(path));
  EXPECT_THAT(message(st), HasSubstr("write failed"));
  EXPECT_EQ(*file_read_all(path), "old");
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"data.txt"});
}

TEST(FileIo, UnwritableDirectoryKeepsTheOldContent) {
  if (::geteuid() == 0) GTEST_SKIP() << "root ignores directory permissions";
  const std::string dir = fresh_dir();
  const std::string path = dir + "/data.txt";
  ASSERT_TRUE(file_write_atomically(path, "old").ok());
  ASSERT_EQ(::chmod(dir.c_str(), 0555), 0);
  const absl::Status st = file_write_atomically(path, "new");
  ::chmod(dir.c_str(), 0755);
  EXPECT_EQ(st.code(), absl::StatusCode::kPermissionDenied) << st;
  EXPECT_THAT(message(st), HasSubstr(path));
  EXPECT_EQ(*file_read_all(path), "old");
  EXPECT_EQ(names_in(dir), std::vector<std::string>{"data.txt"});
}

TEST(FileIo, ErrnoStatusCodes) {
  EXPECT_EQ(errno_status(ENOENT, "x").code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(errno_status(ENOTDIR, "x").code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(errno_status(EACCES, "x").code(), absl::StatusCode::kPermissionDenied);
  EXPECT_EQ(errno_status(EROFS, "x").code(), absl::StatusCode::kPermissionDenied);
  EXPECT_EQ(errno_status(EIO, "x").code(), absl::StatusCode::kInternal);
  EXPECT_EQ(message(errno_status(ENOENT, "some/path: cannot open")),
            "some/path: cannot open: No such file or directory");
}

}  // namespace
}  // namespace ss
