#include "sensors/frame_counts.h"

namespace rangex {

uint64_t FrameIdGaps::next(uint64_t id, bool extended_ids) {
  if (!last_) {
    last_ = id;
    return 0;
  }
  uint64_t lost = 0;
  if (extended_ids) {
    if (id <= *last_) return 0;  // late or repeated
    lost = id - *last_ - 1;
  } else {
    // Ids 1..65535 on a ring of 65535 (0 is never sent): the forward distance; further than
    // half the ring "ahead" is a late or repeated frame.
    const uint64_t d = (id + 65535 - *last_) % 65535;
    if (d == 0 || d >= 32768) return 0;
    lost = d - 1;
  }
  last_ = id;
  return lost;
}

int64_t session_count_offset(bool streamed_before, std::optional<int64_t> newest_at_start,
                             std::optional<int64_t> newest, int64_t first_count, int64_t window) {
  if (!newest) return 0;
  const bool joined_running = newest_at_start && *newest_at_start > window;
  if (!streamed_before && !joined_running) return 0;
  return *newest + 1 - first_count;
}

}  // namespace rangex
