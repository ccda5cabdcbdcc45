#include "pipeline/rectify_table.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/no_value.h"

namespace rangex {

bool exact_plane_point(const CameraModel& cam, const LaserPlane& plane, double u, double v,
                       double& x, double& z) {
  const auto p = plane.intersect(cam.pixel_ray({u, v}));
  if (!p) return false;
  x = p->x;
  z = p->z;
  return true;
}

RectifyTable build_rectify_table(const CameraModel& cam, const LaserPlane& plane, int step) {
  if (step <= 0) fail("rectification table step must be > 0 (got ", step, ")");
  RectifyTable t;
  t.step = step;
  t.nu = (cam.width() - 1 + step - 1) / step + 1;
  t.nv = (cam.height() - 1 + step - 1) / step + 1;
  t.x.resize(size_t(t.nu) * t.nv);
  t.z.resize(t.x.size());
  for (int j = 0; j < t.nv; ++j)
    for (int i = 0; i < t.nu; ++i) {
      double x, z;
      if (!exact_plane_point(cam, plane, double(i) * step, double(j) * step, x, z))
        fail("camera pixel (", i * step, ", ", j * step, ") does not see the laser plane");
      t.x[size_t(j) * t.nu + i] = float(x);
      t.z[size_t(j) * t.nu + i] = float(z);
    }
  return t;
}

void rectify(const float* row, const uint8_t* valid, int count, int width, const int* slot,
             const RectifyTable* tables, float* x, float* z, uint8_t* out_valid) {
  for (int f = 0; f < count; ++f) {
    const RectifyTable& t = tables[slot[f]];
    const float inv = 1.0f / float(t.step);
    for (int c = 0; c < width; ++c) {
      const size_t o = size_t(f) * width + c;
      if (!valid[o]) {
        x[o] = z[o] = kNaN;
        out_valid[o] = 0;
        continue;
      }
      const float gu = float(c) * inv, gv = row[o] * inv;
      const int i = std::min(int(gu), t.nu - 2);
      const int j = std::clamp(int(std::floor(gv)), 0, t.nv - 2);
      const float fu = gu - float(i), fv = gv - float(j);
      const size_t n00 = size_t(j) * t.nu + i, n10 = n00 + 1, n01 = n00 + t.nu, n11 = n01 + 1;
      const float w00 = (1 - fu) * (1 - fv), w10 = fu * (1 - fv), w01 = (1 - fu) * fv,
                  w11 = fu * fv;
      x[o] = w00 * t.x[n00] + w10 * t.x[n10] + w01 * t.x[n01] + w11 * t.x[n11];
      z[o] = w00 * t.z[n00] + w10 * t.z[n10] + w01 * t.z[n01] + w11 * t.z[n11];
      out_valid[o] = 1;
    }
  }
}

}  // namespace rangex
