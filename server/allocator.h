// The server's allocator: jemalloc (Debian's libjemalloc2), linked into the server in place of glibc's malloc, and
// the server's resident memory (docs/performance.md, "Memory of a server").
//
// Why jemalloc: the server's ticks allocate and free many short-lived buffers on gRPC's handler threads, and glibc's
// malloc was 11 % of the server's profile on an AVX2 machine, where the same binary with jemalloc preloaded served
// 1.22x the steps/s (docs/performance.md; jemalloc is below 1 % of the profile). Why not glibc's arenas as before: each thread that allocates gets one of up to 8 x cores glibc arenas, a
// freed block goes back to its arena, which keeps the pages, so RSS stepped up from round to round of identical load
// while the bytes in use did not (tests/integration/memory_rounds.py: 301 -> 471 MB over 8 rounds); the server then
// capped the arenas and called malloc_trim(0). jemalloc gives unused dirty pages back to the kernel on its own after
// dirty_decay_ms (10 s by default) and on demand (arena purge), which is what allocator_trim does from the reaper
// after sessions close (--malloc_trim_s): faults_test's rounds end at 42-43 MB each. jemalloc's own settings come
// from malloc_conf.cc, then MALLOC_CONF (e.g. narenas:4); longer decays or a larger thread cache measured inside the
// noise.
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/statusor.h"

namespace ss::server {

struct AllocatorStats {
  uint64_t in_use = 0;    // bytes handed out and not freed (jemalloc stats.allocated)
  uint64_t free = 0;      // bytes resident in the allocator beyond those in use: dirty pages, metadata, slack
                          // (stats.resident - stats.allocated)
  uint64_t resident = 0;  // the process's resident set (/proc/self/statm)
};

// jemalloc's version when jemalloc serves this process's malloc (checked by allocating); FAILED_PRECONDITION
// otherwise, saying why (the server then refuses to start: its memory controls and figures are jemalloc's).
absl::StatusOr<std::string> allocator_version();
// Gives every arena's unused dirty pages back to the kernel now (arena purge); the bytes RSS fell by.
int64_t allocator_trim();
AllocatorStats allocator_stats();

}  // namespace ss::server
