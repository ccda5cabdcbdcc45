// Giving freed heap back to the system. A soak at a plant's load keeps its live heap flat
// (heaptrack: 772 MB in the first minutes, 770 MB after 20), yet resident memory stepped up
// over an hour: glibc keeps freed pages in each thread's arena (gRPC's threads, the
// gate's workers, the engine's) and returns them only at an arena's top. malloc_trim returns
// every whole free page of every arena.
#pragma once
#include <cstddef>

namespace rangex {

// Returns freed heap pages to the system; the resident bytes that went back (0 when
// nothing did, or where it cannot be measured).
size_t return_free_heap();

}  // namespace rangex
