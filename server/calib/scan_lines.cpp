#include "calib/scan_lines.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/text_file.h"
#include "pipeline/stripe_extract.h"

namespace rangex {

std::vector<float> scan_stripe_rows(const RecordingReader& rec, int lane, int cam,
                                    const StripeParams& params) {
  const RecordingInfo& info = rec.info();
  const int W = info.width, H = info.height;
  StripeSlot slot{params, {}};
  slot.params.method = StripeMethod::kCentroid;
  std::vector<uint8_t> frames(size_t(W) * H * 64);
  std::vector<int> slots(64, 0);
  StripeOutput so;
  std::vector<float> rows;
  rows.reserve(size_t(info.lines) * W);
  for (int64_t n0 = 0; n0 < info.lines; n0 += 64) {
    const int count = int(std::min<int64_t>(64, info.lines - n0));
    rec.read(lane, n0, count, cam == 0 ? frames.data() : nullptr,
             cam == 1 ? frames.data() : nullptr, nullptr, nullptr);
    extract_stripes(frames.data(), count, W, H, slots.data(), &slot, so);
    for (size_t i = 0; i < size_t(count) * W; ++i)
      rows.push_back(so.valid[i] ? so.row[i] : std::nanf(""));
  }
  return rows;
}

std::vector<uint16_t> scan_xray_lines(const RecordingReader& rec, int lane) {
  const RecordingInfo& info = rec.info();
  std::vector<uint16_t> x(size_t(info.lines) * info.xray_pixels);
  rec.read(lane, 0, info.lines, nullptr, nullptr, x.data(), nullptr);
  return x;
}

std::string read_scan_drawing(const std::string& scan_dir, const std::string& name) {
  return read_text_file((std::filesystem::path(scan_dir) / name).string(),
                        "the object's drawing belongs beside the scan");
}

}  // namespace rangex
