// glibc malloc and the server's resident memory (issue 13; README, Faults and Soak). Each thread that allocates gets
// one of up to 8 x cores malloc arenas; a freed block goes back to its arena, which keeps the pages (it gives back
// only a heap's top beyond the trim threshold, which glibc's dynamic mmap threshold raises up to 64 MB, the same rule
// that puts buffers of up to 32 MB in the arenas rather than in mmaps of their own). gRPC's
// handler threads, which run the engine's ticks, spread the ticks' buffers over many arenas, so after sessions close
// what they used stays resident and RSS steps up from round to round of identical load while the bytes in use do
// not. Measured with tests/integration/memory_rounds.py (8 rounds of 16 sessions x 20 steps plus faults_test's
// faults, every session closed; RSS 3 s after each round; --threads=2; mallinfo2 said 9 MB in use after every round
// in every variant): glibc's defaults 301 -> 336 -> 386 -> ... -> 471 MB (free held by malloc 272 -> 441 MB); arenas
// capped at 2: 164-197 MB; malloc_trim(0) 1 s after closes alone: 101-141 MB (malloc_trim does not give back the
// top of a thread arena's heap, so with many arenas much stays); both: 30-52 MB (30 MB at start); 4 arenas and the
// trim: 33-68 MB. 2 arenas cost throughput (16 clients: 38 steps/s against 44-46 with glibc's 16 or with 4 or 8,
// interleaved runs), 4 did not measurably. Hence by default: --threads + 2 arenas (4 here), set at start, and a trim
// from the reaper after sessions close (--malloc_trim_s; one took 5-21 ms with 2 arenas).
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
