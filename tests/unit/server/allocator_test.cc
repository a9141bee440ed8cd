// The server's allocator (server/allocator.h): jemalloc serves malloc in the server library's binaries, its
// statistics follow what is allocated, and a purge gives freed pages back to the kernel.
#include "server/allocator.h"

#include <gtest/gtest.h>
#include <jemalloc/jemalloc.h>

#include <cstdlib>
#include <cstring>
#include <vector>

namespace ss::server {
namespace {

constexpr uint64_t kMiB = 1 << 20;

TEST(AllocatorTest, JemallocServesMalloc) {
  const absl::StatusOr<std::string> version = allocator_version();
  ASSERT_TRUE(version.ok()) << version.status();
  EXPECT_EQ(version->rfind("jemalloc ", 0), 0u) << *version;
}

// The project's settings (common/malloc_conf.cc) reach jemalloc: no arena of its own for blocks of 8 MiB and more
// (docs/performance.md: with it, a server on many maps faulted their pages in again and again).
TEST(AllocatorTest, TheProjectsSettingsReachJemalloc) {
  size_t threshold = 1, size = sizeof threshold;
  ASSERT_EQ(mallctl("opt.oversize_threshold", &threshold, &size, nullptr, 0), 0);
  EXPECT_EQ(threshold, 0u) << "malloc_conf's oversize_threshold:0 did not reach jemalloc";
}

TEST(AllocatorTest, StatsFollowWhatIsAllocated) {
  const AllocatorStats before = allocator_stats();
  std::vector<char*> blocks;
  for (int i = 0; i < 64; ++i) {
    blocks.push_back(static_cast<char*>(std::malloc(kMiB)));
    std::memset(blocks.back(), 1, kMiB);  // touched, so resident
  }
  const AllocatorStats held = allocator_stats();
  // Within a few MiB: what gtest itself allocates and frees meanwhile moves the count a little.
  EXPECT_GE(held.in_use, before.in_use + 60 * kMiB);
  EXPECT_LT(held.in_use, before.in_use + 68 * kMiB);
  EXPECT_GE(held.resident, before.resident + 60 * kMiB);
  for (char* b : blocks) std::free(b);
  const AllocatorStats freed = allocator_stats();
  EXPECT_LT(freed.in_use, held.in_use - 60 * kMiB);
}

TEST(AllocatorTest, APurgeGivesFreedPagesBack) {
  // 64 MiB touched and freed stays partly resident in jemalloc (dirty pages, until their decay: jemalloc already
  // gives some back as it frees, 26-30 MiB here); the purge returns the rest.
  std::vector<char*> blocks;
  for (int i = 0; i < 64; ++i) {
    blocks.push_back(static_cast<char*>(std::malloc(kMiB)));
    std::memset(blocks.back(), 1, kMiB);
  }
  for (char* b : blocks) std::free(b);
  const AllocatorStats dirty = allocator_stats();
  EXPECT_GE(dirty.free, 16 * kMiB) << "freed pages not held: jemalloc's decay may be off (MALLOC_CONF)";
  const int64_t released = allocator_trim();
  EXPECT_GE(released, static_cast<int64_t>(16 * kMiB));
  EXPECT_LT(allocator_stats().free, dirty.free - 16 * kMiB);
}

}  // namespace
}  // namespace ss::server
