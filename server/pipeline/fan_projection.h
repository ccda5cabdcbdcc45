// Stage 3b, fan-beam projection (Laser Range Imaging eq. 39-40): for every X-ray detector pixel,
// the length of its ray from the source through the meat described by the fused profile. Output is
// one thickness line in mm of X-ray path, registered to the detector pixels.
#pragma once
#include <cstdint>

#include "core/fan_beam.h"
#include "core/lane_config.h"

namespace rangex {

// profile: lines * grid_n; lane_slot[l] picks the line's fusion grid and fan beam; all fan
// beams must share `pixels`. Output: lines * pixels thickness and validity.
void project_fan_beam(const float* profile, const uint8_t* profile_valid, int lines, int grid_n,
                      const int* lane_slot, const FusionParams* grids, const FanBeam* beams,
                      int pixels, float* thickness, uint8_t* thickness_valid);

}  // namespace rangex
