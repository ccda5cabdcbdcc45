#include "pipeline/closure_spread.h"

#include <algorithm>
#include <cmath>

namespace rangex {

namespace {

// Box dilation by `reach` along one axis (a running count over the window).
std::vector<uint8_t> dilate(const std::vector<uint8_t>& in, int rows, int cols, int reach,
                            bool along_rows) {
  std::vector<uint8_t> out(in.size(), 0);
  const int lines = along_rows ? rows : cols, len = along_rows ? cols : rows;
  auto at = [&](int line, int k) {
    return along_rows ? size_t(line) * cols + k : size_t(k) * cols + line;
  };
  for (int l = 0; l < lines; ++l) {
    int count = 0;
    for (int k = 0; k < std::min(reach, len); ++k) count += in[at(l, k)];
    for (int k = 0; k < len; ++k) {
      if (k + reach < len) count += in[at(l, k + reach)];
      if (k - reach - 1 >= 0) count -= in[at(l, k - reach - 1)];
      out[at(l, k)] = count > 0;
    }
  }
  return out;
}

}  // namespace

ClosureReach closure_reach(std::vector<float> e, const uint8_t* use, int rows, int cols,
                           int reach) {
  ClosureReach cr;
  const size_t n = size_t(rows) * cols;
  if (e.size() != n) return cr;
  std::vector<uint8_t> closed(n, 0);
  bool any = false;
  for (size_t i = 0; i < n; ++i) {
    if (!use[i] || !(e[i] > 0)) e[i] = 0;
    closed[i] = e[i] > 0;
    any = any || closed[i];
  }
  if (!any) return cr;
  const std::vector<uint8_t> near =
      dilate(dilate(closed, rows, cols, reach, true), rows, cols, reach, false);
  for (size_t i = 0; i < n; ++i) {
    if (near[i] && use[i]) cr.near.push_back(i);
    if (closed[i]) cr.closed.push_back(i);
  }
  cr.e = std::move(e);
  return cr;
}

void discount_closures(std::vector<float>& v, const ClosureReach& cr, const float* thickness,
                       const SpreadProfile& s, const std::vector<double>& sums) {
  if (cr.empty() || s.centre_mm.empty()) return;
  for (size_t k = 0; k < cr.near.size(); ++k) {
    const size_t i = cr.near[k];
    if (!std::isfinite(v[i])) continue;
    const double t = std::isfinite(thickness[i]) ? thickness[i] : s.centre_mm.front();
    const double c = sums[k] / s.scale_at(t);
    v[i] = float(v[i] / std::sqrt(1 + c * c));
  }
}

std::vector<double> closure_kernel_sums(const ClosureReach& cr, int rows, int cols,
                                        const std::vector<double>& taps, int radius,
                                        std::vector<double>& acc) {
  const int w = 2 * radius + 1;
  // The pixel (r, c) reads tap (i, j) from (r + i - radius, c + j - radius): the closed pixel
  // (q, p) gives tap (i, j) to (q - i + radius, p - j + radius).
  auto scatter = [&](bool add) {
    for (size_t src : cr.closed) {
      const int q = int(src / size_t(cols)), p = int(src % size_t(cols));
      const double e = cr.e[src];
      for (int i = 0; i < w; ++i) {
        const int r = q - i + radius;
        if (r < 0 || r >= rows) continue;
        double* row = &acc[size_t(r) * size_t(cols)];
        const double* h = &taps[size_t(i) * size_t(w)];
        for (int j = 0; j < w; ++j) {
          const int c = p - j + radius;
          if (c < 0 || c >= cols) continue;
          if (add)
            row[c] += h[j] * e;
          else
            row[c] = 0;
        }
      }
    }
  };
  scatter(true);
  std::vector<double> sums(cr.near.size());
  for (size_t k = 0; k < cr.near.size(); ++k) sums[k] = acc[cr.near[k]];
  scatter(false);
  return sums;
}

}  // namespace rangex
