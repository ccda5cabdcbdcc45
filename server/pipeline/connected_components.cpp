#include "pipeline/connected_components.h"

#include <algorithm>

namespace rangex {

std::vector<Component> label_components(const uint8_t* on, int rows, int cols,
                                        std::vector<int>& labels) {
  labels.assign(size_t(rows) * cols, 0);
  std::vector<Component> comps;
  std::vector<int> stack;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const size_t i = size_t(r) * cols + c;
      if (!on[i] || labels[i]) continue;
      Component k;
      k.label = int(comps.size()) + 1;
      k.row0 = k.row1 = r;
      k.col0 = k.col1 = c;
      labels[i] = k.label;
      stack.assign(1, int(i));
      while (!stack.empty()) {  // flood fill, explicit stack: fillets are large
        const int j = stack.back();
        stack.pop_back();
        const int jr = j / cols, jc = j % cols;
        ++k.pixels;
        k.row0 = std::min(k.row0, jr);
        k.row1 = std::max(k.row1, jr);
        k.col0 = std::min(k.col0, jc);
        k.col1 = std::max(k.col1, jc);
        for (int dr = -1; dr <= 1; ++dr)
          for (int dc = -1; dc <= 1; ++dc) {
            const int nr = jr + dr, nc = jc + dc;
            if (nr < 0 || nc < 0 || nr >= rows || nc >= cols) continue;
            const size_t n = size_t(nr) * cols + nc;
            if (on[n] && !labels[n]) {
              labels[n] = k.label;
              stack.push_back(int(n));
            }
          }
      }
      comps.push_back(k);
    }
  return comps;
}

}  // namespace rangex
