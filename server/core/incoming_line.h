// A line as the server takes it in: the raw bytes moved out of the gRPC message or lent by a
// GigE Vision receive buffer (the frames are copied once more, into the backend's staging),
// and the same line once queued.
#pragma once
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "core/line_bytes.h"

namespace rangex {

struct IncomingLine {
  int lane = 0;
  int64_t encoder = 0;
  LineBytes cam0, cam1, xray;  // raw bytes as received
  LineBytes xray_high;         // a dual-energy lane's high-energy line (xray is the low one)
  std::string calibration_id;  // what the sender believes active; empty: not checked
  // The sending stream's count of its lines waiting in the queue (for its credit); the
  // engine adds the line when it takes it and removes it when the worker does.
  std::shared_ptr<std::atomic<int>> queued_by;
};

struct QueuedLine {
  IncomingLine line;
  int64_t arrived_ns = 0;
  std::string restart;  // the lane restarts before this line (why)
};

}  // namespace rangex
