// jemalloc's settings for every program that allocates with it (the server, `scenestreamer`, the benches: the
// scenestreamer_jemalloc target compiles this file into each). jemalloc reads this string once at start-up, before
// MALLOC_CONF, which can still override it.
//
// oversize_threshold:0 — no arena of their own for allocations of 8 MiB and more (jemalloc 5.3's "oversize" arena,
// whose decay it sets to 0): they come from the ordinary arenas, which reuse freed pages. Encoding a map allocates
// tens of MiB of such matrices (the PointNet over a map's ~20,000 vectors), and a server that opens sessions on many
// maps faulted their pages in again and again (12 us a page on a 2-vCPU Zen 5 VM). With 32 sessions on 32 maps
// (`scenestreamer-load --scenarios 32 --densify 64`) this setting cut the server's page faults from 337-356k to
// 175-277k and raised steps/s from 71-78 to 83-88 (four interleaved rounds, docs/performance.md); on one map it changed
// nothing (0.98x, five rounds).
extern "C" {
const char* malloc_conf = "oversize_threshold:0";
}
