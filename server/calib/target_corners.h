// Checkerboard corners in one Mono8 frame, found with OpenCV and refined to sub-pixel.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/vec.h"

namespace rangex {

// The cols x rows inner corners in OpenCV's row-major order (which may start from either
// end of the board: the pose absorbs it), or nothing when the board is not found.
std::optional<std::vector<Vec2>> find_target_corners(const uint8_t* frame, int width, int height,
                                                     int cols, int rows);

}  // namespace rangex
