#include "pipeline/fillet_images.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

#include "core/png_io.h"

namespace fs = std::filesystem;

namespace rangex {

namespace {
uint16_t clamp16(double v) {
  return uint16_t(std::clamp(std::lround(v), 0L, 65535L));
}
}  // namespace

void write_fillet_images(const std::string& dir, const FilletImage& img, const FilletResult& r) {
  fs::create_directories(dir);
  const int W = img.cols, H = img.rows;
  const size_t n = img.size();
  write_png16((fs::path(dir) / "xray.png").string(), img.xray.data(), W, H);
  if (!img.xray_high.empty())
    write_png16((fs::path(dir) / "xray_high.png").string(), img.xray_high.data(), W, H);
  std::vector<uint16_t> t(n), p(n), res(n);
  for (size_t i = 0; i < n; ++i) {
    t[i] = std::isfinite(img.thickness[i]) ? clamp16(img.thickness[i] * 100.0) : 65535;
    const bool have = i < r.pseudo.size() && std::isfinite(r.pseudo[i]);
    p[i] = have ? clamp16(r.pseudo[i]) : 0;
    res[i] = have ? clamp16(double(img.xray[i]) - r.pseudo[i] + 32768.0) : 32768;
  }
  write_png16((fs::path(dir) / "thickness.png").string(), t.data(), W, H);
  if (!r.pseudo.empty()) {
    write_png16((fs::path(dir) / "pseudo_xray.png").string(), p.data(), W, H);
    write_png16((fs::path(dir) / "residual.png").string(), res.data(), W, H);
  }
  // Dual energy: bone-equivalent length in um + 32768 (32768 off the fillet), and the fat's
  // share of the soft tissue in 1/65535 (0 off the fillet).
  if (!r.bone_mm.empty()) {
    std::vector<uint16_t> bone(n), fat(n, 0);
    for (size_t i = 0; i < n; ++i)
      bone[i] = std::isfinite(r.bone_mm[i]) ? clamp16(r.bone_mm[i] * 1000.0 + 32768.0) : 32768;
    write_png16((fs::path(dir) / "bone.png").string(), bone.data(), W, H);
    if (r.fat_share.size() == n) {
      for (size_t i = 0; i < n; ++i)
        if (std::isfinite(r.fat_share[i])) fat[i] = clamp16(r.fat_share[i] * 65535.0);
      write_png16((fs::path(dir) / "fat_share.png").string(), fat.data(), W, H);
    }
  }
  // Overlay at twice the size so that millimetre fragments can be seen.
  constexpr int S = 2;
  const double top = double((1 << img.bits) - 1);
  std::vector<uint8_t> rgb(size_t(W * S) * (H * S) * 3);
  auto put = [&](int x, int y, uint8_t R, uint8_t G, uint8_t B) {
    if (x < 0 || y < 0 || x >= W * S || y >= H * S) return;
    uint8_t* q = &rgb[(size_t(y) * W * S + x) * 3];
    q[0] = R, q[1] = G, q[2] = B;
  };
  for (int y = 0; y < H * S; ++y)
    for (int x = 0; x < W * S; ++x) {
      const size_t i = size_t(y / S) * W + x / S;
      const uint8_t g = uint8_t(std::clamp(255.0 * img.xray[i] / top, 0.0, 255.0));
      // Fillet outline in green.
      const bool edge = img.mask[i] &&
                        ((x / S == 0 || !img.mask[i - 1]) || (x / S == W - 1 || !img.mask[i + 1]) ||
                         (y / S == 0 || !img.mask[i - W]) || (y / S == H - 1 || !img.mask[i + W]));
      if (edge)
        put(x, y, 0, 160, 0);
      else
        put(x, y, g, g, g);
    }
  auto box = [&](const Blob& b, uint8_t R, uint8_t G, uint8_t B) {
    const int x0 = (b.col0 - 2) * S, x1 = (b.col1 + 3) * S - 1, y0 = (b.row0 - 2) * S,
              y1 = (b.row1 + 3) * S - 1;
    for (int x = x0; x <= x1; ++x) put(x, y0, R, G, B), put(x, y1, R, G, B);
    for (int y = y0; y <= y1; ++y) put(x0, y, R, G, B), put(x1, y, R, G, B);
  };
  for (const Blob& b : r.air_pockets) box(b, 40, 120, 255);
  for (const Blob& b : r.fragments) box(b, 255, 0, 0);
  write_png8((fs::path(dir) / "overlay.png").string(), rgb.data(), W * S, H * S, 3);
}

}  // namespace rangex
