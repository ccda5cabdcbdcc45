// Stage 3a, two-camera fusion (Laser Range Imaging ch. 4): each camera's (x, z) points, one per
// column, are joined into a polyline and resampled onto the lane's uniform x grid (where a polyline
// folds over itself the higher surface wins: the laser lights the top). Then per grid
// sample: both cameras valid and within agree_tol -> mean; one valid -> that one; both
// valid but disagreeing -> invalid (no guess); finally gaps up to max_gap_mm with valid
// samples on both sides are interpolated, longer gaps stay invalid.
#pragma once
#include <cstdint>

#include "core/lane_config.h"

namespace rangex {

struct FusionStats {
  int64_t both = 0, single = 0, conflict = 0, filled = 0, missing = 0;
  FusionStats& operator+=(const FusionStats& o) {
    both += o.both, single += o.single, conflict += o.conflict, filled += o.filled,
        missing += o.missing;
    return *this;
  }
};

// x, z, valid: frames laid out as [line][camera 0|1][column]. lane_slot[l] picks line l's
// fusion settings; all slots must share grid_samples = grid_n. Output: profile heights and
// validity, lines * grid_n.
void fuse_profiles(const float* x, const float* z, const uint8_t* valid, int width, int lines,
                   const int* lane_slot, const FusionParams* params, int grid_n, float* profile,
                   uint8_t* profile_valid, FusionStats* stats);

}  // namespace rangex
