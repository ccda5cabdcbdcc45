#include "calib/report_plots.h"

#include <algorithm>
#include <cmath>

#include "core/png_io.h"

namespace rangex {

void plot_points(const std::string& path, const std::vector<Series>& series, double x0, double x1,
                 double y0, double y1, double grid_x, double grid_y, int W, int H) {
  std::vector<unsigned char> img(size_t(W) * H * 3, 255);
  auto put = [&](int px, int py, unsigned char r, unsigned char g, unsigned char b) {
    if (px < 0 || py < 0 || px >= W || py >= H) return;
    unsigned char* p = &img[(size_t(py) * W + px) * 3];
    p[0] = r, p[1] = g, p[2] = b;
  };
  auto to_px = [&](double x) { return int(std::lround((x - x0) / (x1 - x0) * (W - 1))); };
  auto to_py = [&](double y) { return int(std::lround((y1 - y) / (y1 - y0) * (H - 1))); };
  if (grid_x > 0)
    for (double g = std::ceil(x0 / grid_x) * grid_x; g <= x1; g += grid_x)
      for (int py = 0; py < H; ++py) put(to_px(g), py, 225, 225, 225);
  if (grid_y > 0)
    for (double g = std::ceil(y0 / grid_y) * grid_y; g <= y1; g += grid_y)
      for (int px = 0; px < W; ++px) put(px, to_py(g), 225, 225, 225);
  if (y0 < 0 && y1 > 0)
    for (int px = 0; px < W; ++px) put(px, to_py(0), 120, 120, 120);
  for (int px = 0; px < W; ++px) put(px, 0, 0, 0, 0), put(px, H - 1, 0, 0, 0);
  for (int py = 0; py < H; ++py) put(0, py, 0, 0, 0), put(W - 1, py, 0, 0, 0);
  for (const Series& s : series)
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      const int cx = to_px(s.x[i]), cy = to_py(std::clamp(s.y[i], y0, y1));
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) put(cx + dx, cy + dy, s.r, s.g, s.b);
    }
  write_png8(path, img.data(), W, H, 3);
}

}  // namespace rangex
