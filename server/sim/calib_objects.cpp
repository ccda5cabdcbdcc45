#include "sim/calib_objects.h"

#include <algorithm>

#include "sim/fillet.h"

namespace rangex::sim {

float CalibScene::height(double x, double b) const {
  double h = 0;
  for (const CalibBox& k : boxes)
    if (x >= k.x0 && x < k.x1 && b >= k.b0 && b < k.b1) h = std::max(h, k.z1);
  return float(h);
}

void CalibScene::slice(double b, float* out, int n) const {
  for (int k = 0; k < n; ++k) out[k] = height(kLaneX0Mm + k * kRasterPitchMm, b);
}

float CalibScene::max_height(double b_lo, double b_hi) const {
  double h = 0;
  for (const CalibBox& k : boxes)
    if (k.b1 >= b_lo && k.b0 <= b_hi) h = std::max(h, k.z1);
  return float(h);
}

double CalibScene::end_b() const {
  double e = 0;
  for (const CalibBox& k : boxes) e = std::max(e, k.b1);
  for (const CalibPin& p : pins) e = std::max(e, p.b1);
  return e;
}

}  // namespace rangex::sim
