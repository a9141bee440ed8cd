// glibc malloc: how the server keeps freed memory from staying resident (README, Faults and Soak). Each thread that
// allocates gets one of up to 8 x cores malloc arenas; a freed block goes back to its arena, which keeps the pages
// unless they are at the top of its heap. gRPC's handler threads (which run the engine's ticks) come and go and touch
// many arenas, so after sessions close much of the memory they held stays resident, spread over the arenas, and RSS
// steps up from round to round of identical load although the bytes in use do not.
#pragma once

#include <cstdint>

namespace ss::server {

struct AllocatorStats {
  uint64_t in_use = 0;    // bytes malloc handed out and not freed (mallinfo2 uordblks + hblkhd)
  uint64_t free = 0;      // bytes held by malloc's arenas, free, not given back (mallinfo2 fordblks)
  uint64_t resident = 0;  // the process's resident set (/proc/self/statm)
};

// Caps the malloc arenas at `arena_max` (mallopt M_ARENA_MAX); 0 leaves glibc's default (8 x cores). Call before
// threads start.
void allocator_set_arena_max(int arena_max);
// Returns the free pages of every arena to the kernel (malloc_trim(0)); the bytes RSS fell by.
int64_t allocator_trim();
AllocatorStats allocator_stats();

}  // namespace ss::server
