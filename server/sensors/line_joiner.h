// A lane's frames from its three devices (two laser cameras, the X-ray detector) joined into
// lines by count, in count order. A count that one device never delivers while the others
// have moved past it (a lost frame or packets) is an incomplete line: it is not emitted (the
// lane sees a missing line, which the assembly bridges or ends the fillet on) and the device
// that lacked it is counted. Thread-safe: each device's thread adds its own frames.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>

#include "core/line_bytes.h"

namespace rangex {

constexpr int kLaneDevices = 3;  // cam0, cam1, xray

struct JoinerStats {
  uint64_t lines = 0;                           // complete lines emitted
  uint64_t incomplete = 0;                      // counts some device lacked
  std::array<uint64_t, kLaneDevices> lacked{};  // per device: incomplete lines it lacked
  std::array<uint64_t, kLaneDevices> stale{};   // per device: frames at or behind its last count
};

class LineJoiner {
 public:
  using Emit = std::function<void(int64_t count, std::array<LineBytes, kLaneDevices>&& frames)>;
  // `window`: how far (in counts) one device may lag the newest frame before its line is
  // given up as incomplete.
  LineJoiner(Emit emit, int64_t window = 64);

  void add(int device, int64_t count, LineBytes frame);
  // Forgets every partial line and where each device was (the lane restarts).
  void reset();
  // The newest count any device has delivered (none before the first frame).
  std::optional<int64_t> newest() const;
  int64_t window() const { return window_; }
  JoinerStats stats() const;

 private:
  struct Partial {
    std::array<LineBytes, kLaneDevices> frames;
    unsigned mask = 0;
  };
  void advance();  // under mu_
  void give_up(Partial* p);

  Emit emit_;
  const int64_t window_;
  mutable std::mutex mu_;
  std::map<int64_t, Partial> pending_;
  std::array<std::optional<int64_t>, kLaneDevices> latest_;
  std::optional<int64_t> next_;  // the next count to emit, once every device has a frame
  int64_t newest_ = INT64_MIN;
  JoinerStats stats_;
};

}  // namespace rangex
