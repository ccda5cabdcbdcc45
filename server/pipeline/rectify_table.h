// Stage 2, rectification (Laser Range Imaging ch. 6.3.2.6): a bilinear lookup table per camera that
// maps a distorted pixel (u, v) straight to laser-plane coordinates (x, z) in mm. The table is
// built once per calibration from the exact model (iterative undistortion, ray meets the
// laser plane); the hot path only interpolates.
#pragma once
#include <cstdint>
#include <vector>

#include "core/camera_model.h"
#include "core/laser_plane.h"

namespace rangex {

struct RectifyTable {
  int step = 2;             // node spacing in pixels
  int nu = 0, nv = 0;       // nodes across and down; node (i, j) sits at pixel (i*step, j*step)
  std::vector<float> x, z;  // nv * nu, row-major
};

RectifyTable build_rectify_table(const CameraModel& cam, const LaserPlane& plane, int step);

// Exact (table-free) mapping, used to build and to check the table.
bool exact_plane_point(const CameraModel& cam, const LaserPlane& plane, double u, double v,
                       double& x, double& z);

// For each of `count` frames (slot[i] picks its table) and each column: (row -> x, z).
void rectify(const float* row, const uint8_t* valid, int count, int width, const int* slot,
             const RectifyTable* tables, float* x, float* z, uint8_t* out_valid);

}  // namespace rangex
