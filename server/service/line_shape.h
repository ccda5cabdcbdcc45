// Admission's first step: a line's shape against its lane's (the frames' and the X-ray line's
// sizes, the encoder's range), before the lane's state is looked at (Engine::submit).
#pragma once
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/incoming_line.h"
#include "service/line_codes.h"

namespace rangex {

struct LaneShape {
  int lane = 0, width = 0, height = 0, pixels = 0;  // Mono8 frames, 16-bit X-ray pixels
  int energies = 1;  // 2: a high-energy X-ray line comes beside the (low-energy) one
};

struct ShapeRefusal {
  Refusal code;
  std::string message;
};

// Bytes of one of the lane's lines: its two frames and its X-ray lines.
size_t line_bytes(const LaneShape& lane);

// The largest message the gRPC port takes (gRPC ends the call past it, RESOURCE_EXHAUSTED):
// twice the size of the largest line still refused in-band (OVERSIZED, past 4 lines), and at
// least 16 MiB for the uploads (a calibration or learned settings and its report).
int max_message_bytes(const std::vector<LaneShape>& lanes);

// nullopt: the line has the lane's shape.
std::optional<ShapeRefusal> check_line_shape(const LaneShape& lane, const IncomingLine& line);

}  // namespace rangex
