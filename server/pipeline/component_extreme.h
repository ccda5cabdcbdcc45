// The extreme a detection threshold acts on: the highest level t at which the pixels with
// v > t hold an 8-connected component of at least `min_pixels` pixels. A fillet is flagged
// exactly when this exceeds the threshold (for a constant threshold), so its distribution
// over clean fillets is what a false-reject budget constrains.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rangex {

// Over the pixels where `use` is set; -infinity when they hold no component that large.
double component_extreme(const float* v, const uint8_t* use, int rows, int cols, int min_pixels);
// The same over a list of pixel indices (a thickness band's, gathered once for every
// statistic); `pixels` is reordered.
double component_extreme(const float* v, std::vector<size_t>& pixels, int rows, int cols,
                         int min_pixels);

}  // namespace rangex
