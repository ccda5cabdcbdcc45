#include "calib/scan_lines.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/text_file.h"
#include "pipeline/recorded_stripes.h"

namespace rangex {

std::vector<float> scan_stripe_rows(const RecordingReader& rec, int lane, int cam,
                                    const StripeParams& params) {
  const RecordingInfo& info = rec.info();
  StripeSlot slot{params, {}};
  slot.params.method = StripeMethod::kCentroid;
  std::vector<float> rows;
  rows.reserve(size_t(info.lines) * info.width);
  for_each_recorded_stripe_batch(rec, lane, cam, slot,
                                 [&](int64_t, int count, const StripeOutput& so) {
                                   for (size_t i = 0; i < size_t(count) * info.width; ++i)
                                     rows.push_back(so.valid[i] ? so.row[i] : std::nanf(""));
                                 });
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
