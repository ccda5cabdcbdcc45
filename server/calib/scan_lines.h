// What the solvers read from a scan (a recording of a calibration object): a camera's
// plain-centroid stripe rows, the X-ray lines, and the object's drawing kept beside it.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "core/recording.h"
#include "core/stripe_params.h"

namespace rangex {

// One camera's stripe rows of a lane, lines x width, NaN where no stripe was found; the
// plain centroid whatever the lane's method (machined objects do not scatter).
std::vector<float> scan_stripe_rows(const RecordingReader& rec, int lane, int cam,
                                    const StripeParams& params);
// A lane's X-ray lines, lines x detector pixels.
std::vector<uint16_t> scan_xray_lines(const RecordingReader& rec, int lane);
// The object's drawing (e.g. staircase.yaml) beside the scan.
std::string read_scan_drawing(const std::string& scan_dir, const std::string& name);

}  // namespace rangex
