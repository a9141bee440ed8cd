#include "server/allocator.h"

#include <jemalloc/jemalloc.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>

#include "absl/strings/str_cat.h"

namespace ss::server {
namespace {

// A jemalloc statistic; 0 when it cannot be read.
uint64_t stat(const char* name) {
  size_t value = 0, size = sizeof value;
  return mallctl(name, &value, &size, nullptr, 0) == 0 ? value : 0;
}

uint64_t resident_bytes() {
  uint64_t bytes = 0;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    unsigned long long size = 0, resident = 0;
    if (std::fscanf(f, "%llu %llu", &size, &resident) == 2) bytes = resident * static_cast<uint64_t>(sysconf(_SC_PAGESIZE));
    std::fclose(f);
  }
  return bytes;
}

}  // namespace

absl::StatusOr<std::string> allocator_version() {
  const char* version = nullptr;
  size_t size = sizeof version;
  if (mallctl("version", &version, &size, nullptr, 0) != 0 || version == nullptr)
    return absl::FailedPreconditionError("the allocator: jemalloc's mallctl(\"version\") failed");
  // jemalloc is linked; does it serve malloc? (It would not if something preloaded another allocator.) Its
  // per-thread byte count must grow by what malloc hands out.
  uint64_t* counter = nullptr;
  size = sizeof counter;
  if (mallctl("thread.allocatedp", &counter, &size, nullptr, 0) != 0 || counter == nullptr)
    return absl::FailedPreconditionError("the allocator: jemalloc's thread.allocatedp is not available");
  // Read through volatile: the compiler takes malloc for a builtin that changes no other memory.
  const volatile uint64_t* count = counter;
  const uint64_t before = *count;
  constexpr size_t kProbe = 1 << 20;
  static void* volatile probe;  // volatile: the compiler may not drop the malloc and free as unused
  probe = std::malloc(kProbe);
  const uint64_t grew = *count - before;
  std::free(probe);
  if (grew < kProbe)
    return absl::FailedPreconditionError(absl::StrCat("the allocator: malloc is not jemalloc's (a 1 MiB malloc added ", grew,
                                                      " bytes to jemalloc's count); is another allocator preloaded?"));
  return absl::StrCat("jemalloc ", version);
}

AllocatorStats allocator_stats() {
  // jemalloc's statistics are a snapshot refreshed by writing the epoch.
  uint64_t epoch = 1;
  size_t size = sizeof epoch;
  mallctl("epoch", &epoch, &size, &epoch, size);
  AllocatorStats s;
  s.in_use = stat("stats.allocated");
  const uint64_t held = stat("stats.resident");
  s.free = held > s.in_use ? held - s.in_use : 0;
  s.resident = resident_bytes();
  return s;
}

int64_t allocator_trim() {
  const uint64_t before = resident_bytes();
  static const std::string purge = absl::StrCat("arena.", MALLCTL_ARENAS_ALL, ".purge");
  mallctl(purge.c_str(), nullptr, nullptr, nullptr, 0);
  return static_cast<int64_t>(before) - static_cast<int64_t>(resident_bytes());
}

}  // namespace ss::server
