#include "line_source.h"

namespace rangex {

void RecordingSource::line(int li, int64_t n, v1::LineScan& out) {
  const auto& info = rec_.info();
  const size_t frame = size_t(info.width) * info.height;
  std::string c0(frame, '\0'), c1(frame, '\0'), x(size_t(info.xray_pixels) * 2, '\0');
  int64_t enc;
  rec_.read(info.lanes[li], n, 1, reinterpret_cast<uint8_t*>(c0.data()),
            reinterpret_cast<uint8_t*>(c1.data()), reinterpret_cast<uint16_t*>(x.data()), &enc);
  out.set_lane(info.lanes[li]);
  out.set_encoder(enc);
  out.set_cam0(std::move(c0));
  out.set_cam1(std::move(c1));
  out.set_xray(std::move(x));
  out.set_calibration_id(info.calibration_id);
}

}  // namespace rangex
