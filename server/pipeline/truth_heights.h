// The height above the belt of each true stripe point: a simulator's truth rows through the
// camera's exact rectification. What evaluation, the scattering calibration and simulated
// plant runs compare measured stripes against, computed in this one place.
#pragma once
#include <cstdint>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/rectify_table.h"

namespace rangex {

class TruthHeights {
 public:
  TruthHeights(const LaneConfig& lane, int camera);
  // `lines` truth rows of `width` columns (NaN: no stripe): z in mm and valid per column.
  void heights(const float* rows, int lines, int width, float* z, uint8_t* valid) const;
  // The same into vectors sized for them.
  void heights(const std::vector<float>& rows, int width, std::vector<float>& z,
               std::vector<uint8_t>& valid) const;

 private:
  RectifyTable table_;
};

}  // namespace rangex
