// Giving freed heap back to the system. A soak at a plant's load keeps its live heap flat
// (heaptrack: 772 MB in the first minutes, 770 MB after 20), yet resident memory stepped up
// over an hour: glibc keeps freed pages in each thread's arena (gRPC's threads, the
// gate's workers, the engine's) and returns them only at an arena's top. malloc_trim returns
// every whole free page of every arena. And glibc raises its mmap threshold each time a
// mapped block is freed, after which blocks of any size come from the arenas and stay there:
// the threshold is fixed. Fixed at 256 kB (until 2026-12-02) it mapped every fillet's
// buffers, and with an arena returning its free top beyond glibc's 128 kB (no longer raised
// once the threshold is fixed) each inspection's pages went back to the kernel and came
// back as page faults in the next: a lane's inspection took 3x its time (docs/concurrency.md).
#pragma once
#include <malloc.h>

#include <cstddef>

namespace rangex {

// Blocks of kMappedBlockBytes and more are mapped and unmapped on their own (a fixed
// threshold, which glibc then no longer raises), and an arena returns its free top only
// beyond kArenaKeptTopBytes (return_free_heap takes the rest back). A fillet's buffers
// (0.1-2 MB) stay below the one and within the other: reused from fillet to fillet, not
// faulted in again. Called once, before the server's threads start. (`bench --path` times an
// inspection thread under it against the earlier 256 kB and 128 kB.)
// Inline: every program of the house (rangexd, rangexctl, the benches) can take it.
constexpr size_t kMappedBlockBytes = size_t(8) << 20, kArenaKeptTopBytes = size_t(32) << 20;
inline void set_server_heap_policy(size_t mapped_block = kMappedBlockBytes,
                                   size_t arena_kept_top = kArenaKeptTopBytes) {
  mallopt(M_MMAP_THRESHOLD, int(mapped_block));
  mallopt(M_TRIM_THRESHOLD, int(arena_kept_top));
}

// Returns freed heap pages to the system; the resident bytes that went back (0 when
// nothing did, or where it cannot be measured).
size_t return_free_heap();

}  // namespace rangex
