// 8-connected components of a binary image, labelled 1..n in scan order.
#pragma once
#include <cstdint>
#include <vector>

namespace rangex {

struct Component {
  int label = 0;
  int pixels = 0;
  int row0 = 0, row1 = 0, col0 = 0, col1 = 0;  // inclusive bounding box
};

// labels: rows * cols, 0 where `on` is 0. Returns the components by label (index = label-1).
std::vector<Component> label_components(const uint8_t* on, int rows, int cols,
                                        std::vector<int>& labels);

}  // namespace rangex
