// Checkerboard corners in one Mono8 frame, found with OpenCV and refined to sub-pixel.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/vec.h"

namespace rangex {

// The cols x rows inner corners in OpenCV's row-major order (which may start from either
// end of the board: the pose absorbs it), refined by a fit of the corner's blurred saddle,
// or nothing when the board is not found. A corner off the board's homography (found
// on the wrong feature, drop_off_grid_corners) is NaN: callers leave it out.
// Sets to NaN each corner of a cols x rows grid that lies more than 1.5 px from the board's
// homography (fitted by RANSAC): a corner found on the wrong feature.
void drop_off_grid_corners(std::vector<Vec2>& corners, int cols, int rows);

std::optional<std::vector<Vec2>> find_target_corners(const uint8_t* frame, int width, int height,
                                                     int cols, int rows);

}  // namespace rangex
