// A device's frame ids. GigE Vision 1.x frame ids are 16 bits and skip 0 (65535 is followed
// by 1); their gaps are frames lost on the way. A device's frames since its start, the lost
// ones included, are its count where it sends no encoder value (free run, or an encoder
// trigger without ChunkEncoderValue).
#pragma once
#include <cstdint>
#include <optional>

namespace rangex {

class FrameIdGaps {
 public:
  // The frames missing before `id` (0 for the first frame, or a repeated or late id).
  uint64_t next(uint64_t id, bool extended_ids = false);
  void reset() { last_.reset(); }

 private:
  std::optional<uint64_t> last_;
};

// Where a device that counts its own frames (no encoder value in its frames) puts them on its
// lane's counts: the offset added to its count, decided at the session's first frame.
// - A device that started with its lane keeps its count, however late its first frame
//   arrives: the lane's devices share the trigger, so its frame n is everyone's pulse n
//   (under load one receive thread can fall far behind the others without missing a pulse).
// - One that rejoins (an earlier session of it streamed) or that started when the lane's
//   newest count was already beyond the joiner's window takes its first frame as the lane's
//   next line: nothing better is known (docs/sensors.md).
// newest_at_start: the lane's newest count when this session's acquisition had started;
// newest: the lane's newest count at its first frame.
int64_t session_count_offset(bool streamed_before, std::optional<int64_t> newest_at_start,
                             std::optional<int64_t> newest, int64_t first_count, int64_t window);

}  // namespace rangex
