#include "calib/open_beam.h"

#include <algorithm>

namespace rangex {

std::vector<double> open_beam(const uint16_t* xray, int64_t lines, int pixels) {
  std::vector<double> open(pixels);
  std::vector<uint16_t> col(lines);
  for (int i = 0; i < pixels; ++i) {
    for (int64_t n = 0; n < lines; ++n) col[n] = xray[n * pixels + i];
    std::nth_element(col.begin(), col.begin() + lines / 2, col.end());
    open[i] = std::max<double>(1.0, col[lines / 2]);
  }
  return open;
}

}  // namespace rangex
