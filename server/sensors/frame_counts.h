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

}  // namespace rangex
