#include "service/line_from_proto.h"

namespace rangex {

IncomingLine take_line(v1::LineScan& l) {
  IncomingLine in;
  in.lane = l.lane();
  in.encoder = l.encoder();
  in.cam0 = std::move(*l.mutable_cam0());
  in.cam1 = std::move(*l.mutable_cam1());
  in.xray = std::move(*l.mutable_xray());
  in.xray_high = std::move(*l.mutable_xray_high());
  in.calibration_id = l.calibration_id();
  return in;
}

}  // namespace rangex
