// A device's frame ids. GigE Vision 1.x frame ids are 16 bits and skip 0 (65535 is followed
// by 1); their gaps are frames lost on the way. A device's frames since its start, the lost
// ones included, are its count where it sends no encoder value (free run, or an encoder
// trigger without ChunkEncoderValue).
#pragma once
#include <array>
#include <cstdint>
#include <optional>

#include "sensors/line_joiner.h"

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
// Whether a session keeps its own count (above): it is the device's first and the lane had
// not run past the joiner's window when it started.
bool keeps_own_count(bool streamed_before, std::optional<int64_t> newest_at_start, int64_t window);

// `to` minus `from` on the frame ids' ring (16 bits without 0, or extended 64-bit ids): the
// nearer way round, negative when `to` is before `from`.
int64_t frame_id_distance(uint64_t from, uint64_t to, bool extended_ids = false);

// The first frame ids of a lane's devices that keep their own counts. They share the
// trigger and started together, so their ids began together: a device whose first frame id
// is k past the earliest one lost k frames before its first (a receiver can drop a
// session's first frames: Aravis's packet socket does at times), and its count moves k on.
// Ids further apart than `kMaxStartLoss` are taken as devices whose ids did not start
// together (they keep their counts). Not thread-safe: the lane holds a lock around it.
class LaneStartIds {
 public:
  static constexpr int64_t kMaxStartLoss = 256;

  // Records device d's first frame id; true when the shift of a device that had already
  // delivered frames changed (the lane's partial lines hold counts that are now wrong).
  bool first(int device, uint64_t id);
  // What device d adds to its own count (0 before its first frame).
  int64_t shift(int device) const { return shift_[size_t(device)]; }

 private:
  std::array<std::optional<uint64_t>, kLaneDevices> first_;
  std::array<int64_t, kLaneDevices> shift_{};
};

}  // namespace rangex
