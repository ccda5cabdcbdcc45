#include "pipeline/wall_gaps.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace rangex {

namespace {

// One line of pixels (stride apart): gaps of NaN between finite ends, at most max_gap long,
// closed with the nearer end's value; `step` gets |end - end| at each.
int close_line(float* t, uint8_t* mask, float* step, int n, size_t stride, int max_gap,
               double floor_mm) {
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
        step[size_t(k) * stride] = std::abs(a - b);
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
  const int R = img.rows, C = img.cols;
  std::vector<float> step(img.size(), 0.0f);
  int closed = 0;
  for (int r = 0; r < R; ++r)
    closed += close_line(&img.thickness[size_t(r) * C], &img.mask[size_t(r) * C],
                         &step[size_t(r) * C], C, 1, max_gap_px, floor_mm);
  for (int c = 0; c < C; ++c)
    closed +=
        close_line(&img.thickness[c], &img.mask[c], &step[c], R, size_t(C), max_gap_px, floor_mm);
  if (std::any_of(step.begin(), step.end(), [](float s) { return s > 0; }))
    img.closure_step_mm = std::move(step);
  return closed;
}

std::vector<float> rim_steps(const FilletImage& img) {
  const int R = img.rows, C = img.cols;
  std::vector<float> step(img.size(), 0.0f);
  auto on = [&](int r, int c) {
    return r >= 0 && r < R && c >= 0 && c < C && img.mask[size_t(r) * C + c] &&
           std::isfinite(img.thickness[size_t(r) * C + c]);
  };
  // The rim pixel (r, c) whose outside lies at (r - dr, c - dc): its inner neighbour is
  // (r + dr, c + dc).
  auto rim = [&](int r, int c, int dr, int dc) -> double {
    if (on(r - dr, c - dc)) return 0;
    const double a = std::max(0.0f, img.thickness[size_t(r) * C + c]);
    const double h =
        on(r + dr, c + dc) ? std::max(a, double(img.thickness[size_t(r + dr) * C + c + dc])) : a;
    if (!(h > 0)) return 0;
    const double b = h - a;
    return std::sqrt((a * a * a + b * b * b) / h);
  };
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < C; ++c) {
      if (!on(r, c)) continue;
      const double s = std::max(std::max(rim(r, c, 0, 1), rim(r, c, 0, -1)),
                                std::max(rim(r, c, 1, 0), rim(r, c, -1, 0)));
      step[size_t(r) * C + c] = float(s);
    }
  return step;
}

std::vector<float> closure_variance(const FilletImage& img, const std::function<double(double)>& mu,
                                    bool rim) {
  const bool closed = img.closure_step_mm.size() == img.size();
  if (!closed && !rim) return {};
  // Without the rim the closures' steps are read where they are, not copied.
  std::vector<float> with_rim;
  if (rim) {
    with_rim = rim_steps(img);
    if (closed)
      for (size_t i = 0; i < with_rim.size(); ++i)
        with_rim[i] = std::max(with_rim[i], img.closure_step_mm[i]);
  }
  const std::vector<float>& steps = rim ? with_rim : img.closure_step_mm;
  const int R = img.rows, C = img.cols;
  std::vector<float> var(img.size(), 0.0f);
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < C; ++c) {
      float step = 0;
      for (int q = std::max(0, r - 1); q <= std::min(R - 1, r + 1); ++q)
        step = std::max(step, steps[size_t(q) * C + c]);
      if (step <= 0) continue;
      const size_t i = size_t(r) * C + c;
      const double t = std::isfinite(img.thickness[i]) ? img.thickness[i] : 0.0;
      const double d = mu(t) * step;
      var[i] = float(d * d / 3);
    }
  return var;
}

}  // namespace rangex
