#include "service/line_shape.h"

#include <algorithm>
#include <climits>

#include "core/error.h"

namespace rangex {

namespace {
constexpr size_t kOversizedLines = 4;  // a line past this many of its lane's is OVERSIZED
constexpr size_t kMinMessageBytes = size_t(16) << 20;
}  // namespace

size_t line_bytes(const LaneShape& l) {
  return 2 * size_t(l.width) * size_t(l.height) + size_t(l.pixels) * 2 * size_t(l.energies);
}

int max_message_bytes(const std::vector<LaneShape>& lanes) {
  size_t most = kMinMessageBytes;
  for (const LaneShape& l : lanes)
    most = std::max(most, 2 * kOversizedLines * line_bytes(l) + (size_t(64) << 10));
  return int(std::min<size_t>(most, INT_MAX));
}

std::optional<ShapeRefusal> check_line_shape(const LaneShape& l, const IncomingLine& line) {
  const size_t frame = size_t(l.width) * size_t(l.height);
  const size_t expected = line_bytes(l);
  const size_t size =
      line.cam0.size() + line.cam1.size() + line.xray.size() + line.xray_high.size();
  if (size > kOversizedLines * expected)
    return ShapeRefusal{Refusal::kOversized, join("line of ", size, " bytes; lane ", l.lane,
                                                  " lines are ", expected, " bytes")};
  if (line.cam0.size() != frame || line.cam1.size() != frame)
    return ShapeRefusal{
        Refusal::kWrongFrameSize,
        join("camera frames of ", line.cam0.size(), " and ", line.cam1.size(), " bytes; lane ",
             l.lane, " expects ", l.width, "x", l.height, " = ", frame)};
  if (line.xray.size() != size_t(l.pixels) * 2)
    return ShapeRefusal{Refusal::kWrongXraySize,
                        join("X-ray line of ", line.xray.size(), " bytes; lane ", l.lane,
                             " expects ", l.pixels, " 16-bit pixels")};
  if (l.energies == 2 && line.xray_high.size() != size_t(l.pixels) * 2)
    return ShapeRefusal{
        Refusal::kWrongXraySize,
        join("high-energy X-ray line of ", line.xray_high.size(), " bytes; lane ", l.lane,
             " has two energies and expects ", l.pixels, " 16-bit pixels in xray_high")};
  if (l.energies == 1 && !line.xray_high.empty())
    return ShapeRefusal{
        Refusal::kWrongXraySize,
        join("a high-energy X-ray line of ", line.xray_high.size(), " bytes; lane ", l.lane,
             " has one energy (plant.yaml xray.energies: 1): xray_high must be "
             "empty")};
  if (line.encoder > kMaxEncoder || line.encoder < -kMaxEncoder)
    return ShapeRefusal{Refusal::kEncoderOutOfRange,
                        join("encoder ", line.encoder, " of lane ", l.lane, " is outside +-2^62")};
  return std::nullopt;
}

}  // namespace rangex
