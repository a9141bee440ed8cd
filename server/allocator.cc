#include "server/allocator.h"

#include <malloc.h>
#include <unistd.h>

#include <cstdio>

namespace ss::server {

void allocator_set_arena_max(int arena_max) {
  if (arena_max > 0) mallopt(M_ARENA_MAX, arena_max);
}

AllocatorStats allocator_stats() {
  AllocatorStats s;
  const struct mallinfo2 m = mallinfo2();
  s.in_use = m.uordblks + m.hblkhd;
  s.free = m.fordblks;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    unsigned long long size = 0, resident = 0;
    if (std::fscanf(f, "%llu %llu", &size, &resident) == 2)
      s.resident = resident * static_cast<uint64_t>(sysconf(_SC_PAGESIZE));
    std::fclose(f);
  }
  return s;
}

int64_t allocator_trim() {
  const uint64_t before = allocator_stats().resident;
  malloc_trim(0);
  return static_cast<int64_t>(before) - static_cast<int64_t>(allocator_stats().resident);
}

}  // namespace ss::server
