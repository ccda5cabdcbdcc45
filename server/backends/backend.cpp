#include "backends/backend.h"

#include <algorithm>

namespace rangex {

void run_batch(Backend& b, const uint8_t* frames, int lines, const int* lane_slot,
               LineResults& out) {
  const LaneConfig& l = b.lane(0);
  const size_t bytes = size_t(lines) * 2 * size_t(l.frame_width) * size_t(l.frame_height);
  LineBatchSlot& s = b.acquire(lines);
  std::copy_n(frames, bytes, s.frames());
  std::copy_n(lane_slot, lines, s.lane_slot());
  b.submit(s);
  b.collect(s, out);
}

}  // namespace rangex
