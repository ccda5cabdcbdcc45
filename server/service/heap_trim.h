// Giving freed heap back to the system. A soak at a plant's load keeps its live heap flat
// (heaptrack: 772 MB in the first minutes, 770 MB after 20), yet resident memory stepped up
// over an hour: glibc keeps freed pages in each thread's arena (gRPC's threads, the
// gate's workers, the engine's) and returns them only at an arena's top. malloc_trim returns
// every whole free page of every arena. And large blocks (frames, fillet images) are kept out
// of the arenas: glibc raises its mmap threshold each time a mapped block is freed, after which
// blocks of a few MB come from the arenas and stay there.
// Between those trims an arena keeps what is freed at its top: with glibc's default (128 kB,
// fixed once the mmap threshold is) each inspection's buffers of 100-250 kB went back to the
// kernel as they were freed and came back as page faults in the next fillet's.
#pragma once
#include <cstddef>

namespace rangex {

// Blocks of kMappedBlockBytes and more are mapped and unmapped on their own (a fixed
// threshold, which glibc then no longer raises), and an arena returns its free top only
// beyond kArenaKeptTopBytes (return_free_heap takes the rest back). A fillet's buffers
// (0.1-2 MB) stay below the one and within the other: reused from fillet to fillet, not
// faulted in again. Called once, before the server's threads start. (`bench --path` times an
// inspection thread under it against the earlier 256 kB and 128 kB.)
constexpr size_t kMappedBlockBytes = size_t(8) << 20, kArenaKeptTopBytes = size_t(32) << 20;
void set_server_heap_policy(size_t mapped_block = kMappedBlockBytes,
                            size_t arena_kept_top = kArenaKeptTopBytes);

// Returns freed heap pages to the system; the resident bytes that went back (0 when
// nothing did, or where it cannot be measured).
size_t return_free_heap();

}  // namespace rangex
