#include "pipeline/truth_heights.h"

#include <cmath>

namespace rangex {

TruthHeights::TruthHeights(const LaneConfig& lane, int camera)
    : table_(build_rectify_table(lane.cameras[camera].model, lane.laser, lane.lut_step_px)) {}

void TruthHeights::heights(const float* rows, int lines, int width, float* z,
                           uint8_t* valid) const {
  const size_t n = size_t(lines) * size_t(width);
  std::vector<uint8_t> in(n);
  std::vector<float> x(n);
  std::vector<int> slot(size_t(lines), 0);
  for (size_t i = 0; i < n; ++i) in[i] = std::isfinite(rows[i]);
  rectify(rows, in.data(), lines, width, slot.data(), &table_, x.data(), z, valid);
}

void TruthHeights::heights(const std::vector<float>& rows, int width, std::vector<float>& z,
                           std::vector<uint8_t>& valid) const {
  const int lines = int(rows.size() / size_t(width));
  z.resize(rows.size());
  valid.resize(rows.size());
  heights(rows.data(), lines, width, z.data(), valid.data());
}

}  // namespace rangex
