// The per-lane tables the kernels read (kernels/shared/lane_tables.h), packed for upload:
// stripe settings and rectification tables per (lane, camera), fusion grid and fan beam per
// lane, and the ln table of the 3-point Gaussian. Rectification tables are built from the
// exact camera model once per lane configuration and kept, so that updating one lane
// (a calibration activation) repacks without rebuilding the others.
#pragma once
#include <vector>

#include "core/lane_config.h"
#include "pipeline/rectify_table.h"
#include "shared/lane_tables.h"

namespace rangex {

class KernelTables {
 public:
  void set_lanes(const std::vector<LaneConfig>& lanes);
  void update_lane(int slot, const LaneConfig& lane);

  int width = 0, height = 0, grid_n = 0, pixels = 0;
  std::vector<kernel::StripeSlotK> stripe;  // [lane][camera]
  std::vector<kernel::RectTableK> rect;     // [lane][camera]
  std::vector<float> nodes;                 // every table's x then z nodes
  std::vector<kernel::LaneGeomK> geom;      // [lane]
  std::vector<float> ln;                    // ln(max(g, 1)) for g = 0..255

 private:
  void pack();
  std::vector<LaneConfig> lanes_;
  std::vector<RectifyTable> tables_;  // [lane][camera]
};

}  // namespace rangex
