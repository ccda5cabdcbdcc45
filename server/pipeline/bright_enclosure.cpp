#include "pipeline/bright_enclosure.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rangex {

void bright_enclosure_excess(const float* z, const uint8_t* use, int rows, int cols, float top,
                             int reach, std::vector<float>& excess) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float none = -std::numeric_limits<float>::infinity();
  const size_t n = size_t(rows) * size_t(cols);
  excess.assign(n, nan);
  static constexpr int kLines[4][2] = {{0, 1}, {1, 0}, {1, 1}, {1, -1}};  // (row, col) steps
  // The brightest usable value k = 1..reach steps from (r, c) along (dr, dc).
  auto brightest = [&](int r, int c, int dr, int dc) {
    float m = none;
    for (int k = 1; k <= reach; ++k) {
      const int rr = r + k * dr, cc = c + k * dc;
      if (rr < 0 || rr >= rows || cc < 0 || cc >= cols) break;
      const size_t j = size_t(rr) * cols + size_t(cc);
      if (use[j] && std::isfinite(z[j])) m = std::max(m, z[j]);
    }
    return m;
  };
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const size_t i = size_t(r) * cols + size_t(c);
      if (!use[i] || !std::isfinite(z[i])) continue;
      float level = std::numeric_limits<float>::infinity();
      for (int l = 0; l < 4 && level > top && reach > 0; ++l) {
        const int dr = kLines[l][0], dc = kLines[l][1];
        level = std::min(level, std::min(brightest(r, c, dr, dc), brightest(r, c, -dr, -dc)));
      }
      excess[i] = reach > 0 && level > top ? level - top : 0.f;
    }
}

}  // namespace rangex
