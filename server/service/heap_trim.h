// Giving freed heap back to the system. A soak at a plant's load keeps its live heap flat
// (heaptrack: 772 MB in the first minutes, 770 MB after 20), yet resident memory stepped up
// over an hour: glibc keeps freed pages in each thread's arena (gRPC's threads, the
// gate's workers, the engine's) and returns them only at an arena's top. malloc_trim returns
// every whole free page of every arena. And large blocks (frames, fillet images) are kept out
// of the arenas: glibc raises its mmap threshold each time a mapped block is freed, after which
// blocks of a few MB come from the arenas and stay there.
#pragma once
#include <cstddef>

namespace rangex {

// Blocks of 256 kB and more are mapped and unmapped on their own (a fixed threshold, which
// glibc then no longer raises). Called once, before the server's threads start.
void keep_large_blocks_out_of_arenas();

// Returns freed heap pages to the system; the resident bytes that went back (0 when
// nothing did, or where it cannot be measured).
size_t return_free_heap();

}  // namespace rangex
