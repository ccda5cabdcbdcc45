#pragma once

#include <limits>

namespace rangex {

// The value of a sample that has none (no stripe found, no ray, no wall, no thickness): a
// quiet NaN, which every later step carries through and tests with std::isfinite. Widens to
// the double NaN where a double is wanted.
inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace rangex
