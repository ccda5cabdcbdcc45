#include "sensors/frame_counts.h"

namespace rangex {

uint64_t FrameIdGaps::next(uint64_t id, bool extended_ids) {
  if (!last_) {
    last_ = id;
    return 0;
  }
  // Not ahead (further than half the 16-bit ring "ahead" is behind): late or repeated.
  const int64_t d = frame_id_distance(*last_, id, extended_ids);
  if (d <= 0) return 0;
  last_ = id;
  return uint64_t(d - 1);
}

bool keeps_own_count(bool streamed_before, std::optional<int64_t> newest_at_start, int64_t window) {
  const bool joined_running = newest_at_start && *newest_at_start > window;
  return !streamed_before && !joined_running;
}

int64_t session_count_offset(bool streamed_before, std::optional<int64_t> newest_at_start,
                             std::optional<int64_t> newest, int64_t first_count, int64_t window) {
  if (!newest || keeps_own_count(streamed_before, newest_at_start, window)) return 0;
  return *newest + 1 - first_count;
}

int64_t frame_id_distance(uint64_t from, uint64_t to, bool extended_ids) {
  if (extended_ids) return int64_t(to - from);  // two's complement: the nearer way round
  const int64_t d = int64_t((to + 65535 - from % 65535) % 65535);
  return d > 65535 / 2 ? d - 65535 : d;
}

bool LaneStartIds::first(int device, uint64_t id) {
  first_[size_t(device)] = id;
  // The earliest id the others agree with: each device's shift is its distance from it.
  std::optional<uint64_t> earliest;
  for (const auto& f : first_) {
    if (!f) continue;
    const int64_t d = earliest ? frame_id_distance(*earliest, *f) : 0;
    if (!earliest || (d < 0 && -d <= kMaxStartLoss)) earliest = f;
  }
  bool moved = false;
  for (size_t d = 0; d < first_.size(); ++d) {
    int64_t shift = 0;
    if (first_[d]) {
      const int64_t k = frame_id_distance(*earliest, *first_[d]);
      if (k > 0 && k <= kMaxStartLoss) shift = k;
    }
    if (shift != shift_[d] && int(d) != device && first_[d]) moved = true;
    shift_[d] = shift;
  }
  return moved;
}

}  // namespace rangex
