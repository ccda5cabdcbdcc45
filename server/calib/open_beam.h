// The X-ray's open beam per detector pixel in a calibration scan: the median over the
// scan's lines (most of a calibration scan is bare belt), at least 1 DN.
#pragma once
#include <cstdint>
#include <vector>

namespace rangex {

std::vector<double> open_beam(const uint16_t* xray, int64_t lines, int pixels);

}  // namespace rangex
