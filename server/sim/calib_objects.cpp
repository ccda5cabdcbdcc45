#include "sim/calib_objects.h"

#include <algorithm>

#include "sim/fillet.h"

namespace rangex::sim {

float CalibScene::height(double x, double b) const {
  double h = 0;
  for (const CalibBox& k : boxes)
    if (k.covers(x, b)) h = std::max(h, k.z1);
  return float(h);
}

void CalibScene::slice(double b, float* out, int n) const {
  // Each raster node holds the mean height over its own 0.2 mm: the renderer joins nodes
  // by straight segments, so a wall becomes a ramp whose middle is exactly the wall (a
  // point sample would put every wall up to a node's width off).
  constexpr int kSub = 8;
  for (int k = 0; k < n; ++k) {
    double s = 0;
    for (int j = 0; j < kSub; ++j)
      s += height(kLaneX0Mm + (k - 0.5 + (j + 0.5) / kSub) * kRasterPitchMm, b);
    out[k] = float(s / kSub);
  }
}

bool CalibScene::bare(double x_lo, double x_hi, double b_lo, double b_hi) const {
  for (const CalibBox& k : boxes)
    if (k.may_reach(x_lo, x_hi, b_lo, b_hi)) return false;
  return true;
}

float CalibScene::max_height(double b_lo, double b_hi) const {
  double h = 0;
  for (const CalibBox& k : boxes)
    if (k.b1 + (k.x1 - k.x0) >= b_lo && k.b0 - (k.x1 - k.x0) <= b_hi) h = std::max(h, k.z1);
  return float(h);
}

double CalibScene::end_b() const {
  double e = 0;
  for (const CalibBox& k : boxes) e = std::max(e, k.b1 + std::abs(k.sin_yaw()) * (k.x1 - k.x0));
  for (const CalibPin& p : pins) e = std::max(e, p.b1);
  return e;
}

}  // namespace rangex::sim
