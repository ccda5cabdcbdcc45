#include "pipeline/wall_gaps.h"

#include <cmath>

namespace rangex {

namespace {

// One line of pixels (stride apart): gaps of NaN between finite ends, at most max_gap long,
// closed with the nearer end's value.
int close_line(float* t, uint8_t* mask, int n, size_t stride, int max_gap, double floor_mm) {
  int closed = 0;
  for (int i = 0; i < n;) {
    if (std::isfinite(t[size_t(i) * stride])) {
      ++i;
      continue;
    }
    int e = i;
    while (e < n && !std::isfinite(t[size_t(e) * stride])) ++e;
    const int len = e - i;
    if (i > 0 && e < n && len <= max_gap) {
      const float a = t[size_t(i - 1) * stride], b = t[size_t(e) * stride];
      for (int k = i; k < e; ++k) {
        // The first half keeps the near end's height, the second the far end's; an odd
        // middle pixel takes the lower (the wall's foot is what was hidden).
        const int from_a = k - i, from_b = e - 1 - k;
        const float v = from_a < from_b ? a : from_b < from_a ? b : std::min(a, b);
        t[size_t(k) * stride] = v;
        if (v > floor_mm) mask[size_t(k) * stride] = 1;
        ++closed;
      }
    }
    i = e;
  }
  return closed;
}

}  // namespace

int close_wall_gaps(FilletImage& img, int max_gap_px, double floor_mm) {
  if (max_gap_px <= 0) return 0;
  int closed = 0;
  for (int r = 0; r < img.rows; ++r)
    closed += close_line(&img.thickness[size_t(r) * img.cols], &img.mask[size_t(r) * img.cols],
                         img.cols, 1, max_gap_px, floor_mm);
  for (int c = 0; c < img.cols; ++c)
    closed += close_line(&img.thickness[c], &img.mask[c], img.rows, size_t(img.cols), max_gap_px,
                         floor_mm);
  return closed;
}

}  // namespace rangex
