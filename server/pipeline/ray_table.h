// Fan-beam path lengths from per-pixel ray tables. The geometry of a lane (its fan beam and
// its fusion grid) is fixed between calibrations, so the cells each detector pixel's ray
// crosses between the belt and z_max, and where it enters and leaves them, are found once;
// per line only the heights are read. The walk is core/ray_path.cpp's, step for step, so the
// lengths agree with ray_path_length to the last bit; a line whose top is above z_max falls
// back to the walk.
#pragma once
#include <cstdint>
#include <vector>

#include "core/fan_beam.h"
#include "core/lane_config.h"

namespace rangex {

struct RaySegment {
  int32_t cell;   // grid cell [cell, cell + 1]; -1 is the half cell left of sample 0
  double z0, z1;  // the ray's heights entering and leaving it
  double t0, t1;  // the ray's position in the cell there (0: sample cell, 1: cell + 1)
};

struct RayTable {
  double z_max_mm = 0;
  int pixels = 0, grid_n = 0;
  double x0_mm = 0, pitch_mm = 0;
  std::vector<int32_t> first;  // pixels + 1 offsets into seg
  std::vector<RaySegment> seg;
  std::vector<double> xd, zd, slope, sec;  // per pixel: foot, dx/dz, 1 / cos
  FanBeam beam;                            // for the fallback walk
};

RayTable build_ray_table(const FanBeam& fb, const FusionParams& grid, double z_max_mm = 100.0);

// One line: heights h (valid flags hv) of the table's grid -> thickness per pixel.
void project_line(const RayTable& t, const float* h, const uint8_t* hv, float* thickness,
                  uint8_t* thickness_valid);

}  // namespace rangex
