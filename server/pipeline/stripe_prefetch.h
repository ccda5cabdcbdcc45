// A cursor that fetches a batch's next frame towards the cache while the window stages
// compute from the current one (already in cache after the column-maximum scan), so that
// memory transfer overlaps the arithmetic instead of alternating with it.
#pragma once
#include <cstddef>
#include <cstdint>

namespace rangex::stripe {

struct Prefetch {
  const uint8_t* next = nullptr;  // first byte not yet requested
  const uint8_t* end = nullptr;   // end of the batch
  // Lines requested per row the window stages visit: spread thinly, so that the requests
  // never fill the miss queue the stages' own loads and stores need (measured: 3-4
  // best; at 8 or more the stages slow down more than the next scan gains).
  static constexpr int kLinesPerStep = 4;

  void skip_to(const uint8_t* pos) {
    if (next < pos) next = pos;
  }
  void step() {
    for (int k = 0; k < kLinesPerStep && next < end; ++k, next += 64)
      __builtin_prefetch(next, 0, 2);
  }
};

}  // namespace rangex::stripe
