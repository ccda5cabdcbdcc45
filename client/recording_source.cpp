#include "line_source.h"

namespace rangex {

void RecordingSource::line(int li, int64_t n, v1::LineScan& out) {
  const auto& info = rec_.info();
  const size_t frame = size_t(info.width) * info.height;
  // Read into the message's own buffers: a LineScan reused line after line keeps their
  // storage, so a line costs no allocation and no zero-fill (under ThreadSanitizer the fill
  // of two camera frames a line was most of a test's time).
  std::string& c0 = *out.mutable_cam0();
  std::string& c1 = *out.mutable_cam1();
  std::string& x = *out.mutable_xray();
  c0.resize(frame);
  c1.resize(frame);
  x.resize(size_t(info.xray_pixels) * 2);
  int64_t enc;
  rec_.read(info.lanes[li], n, 1, reinterpret_cast<uint8_t*>(c0.data()),
            reinterpret_cast<uint8_t*>(c1.data()), reinterpret_cast<uint16_t*>(x.data()), &enc);
  out.set_lane(info.lanes[li]);
  out.set_encoder(enc);
  out.set_calibration_id(info.calibration_id);
}

}  // namespace rangex
