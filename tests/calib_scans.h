// Simulated calibration scans shared by the calibration tests: a rig whose cameras moved on
// their mounts, a staircase scan by one camera and a blocks scan by both planes.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

#include "calib/staircase_fit.h"
#include "core/lane_config.h"
#include "core/vec.h"
#include "pipeline/stripe_extract.h"
#include "sim/calib_scenes.h"

namespace rangex::calib_test {

// The camera turned (degrees about x, y, z) and shifted on its mount.
inline CameraModel moved(const CameraModel& c, double ax, double ay, double az, Vec3 shift) {
  const Mat3 R = rotation_xyz(ax * M_PI / 180, ay * M_PI / 180, az * M_PI / 180) * c.rotation();
  const Vec3 centre = c.center() + shift;
  return CameraModel(c.intrinsics(), c.distortion(), R, (R * centre) * -1.0, c.width(), c.height());
}

// The default lane with both cameras moved by a few mm and tenths of a degree.
inline LaneConfig moved_rig() {
  LaneConfig rig = default_lane_config(0);
  rig.cameras[0].model = moved(rig.cameras[0].model, 0.4, -0.3, 0.25, {2.0, -3.0, 4.0});
  rig.cameras[1].model = moved(rig.cameras[1].model, -0.35, 0.2, -0.3, {-1.5, 2.5, -3.0});
  return rig;
}

// Plain-centroid stripe rows (machined objects do not scatter), NaN where none.
inline void stripe_rows(const LaneConfig& rig, const uint8_t* frame, std::vector<float>& out) {
  StripeSlot slot{rig.stripe, {}};
  slot.params.method = StripeMethod::kCentroid;
  const int zero = 0;
  StripeOutput so;
  extract_stripes(frame, 1, rig.frame_width, rig.frame_height, &zero, &slot, so);
  for (int u = 0; u < rig.frame_width; ++u) out.push_back(so.valid[u] ? so.row[u] : NAN);
}

// One camera's stripe rows over a scan of `scene` (lines x width).
inline std::vector<float> scan_rows(const LaneConfig& rig, const sim::CalibScene& scene, int cam,
                                    int64_t* lines) {
  const sim::CameraRenderer r(rig, cam);
  *lines = int64_t((scene.end_b() + 30) / rig.encoder_step_mm);
  std::vector<uint8_t> frame(size_t(rig.frame_width) * rig.frame_height);
  std::vector<float> truth(rig.frame_width), rows;
  for (int64_t n = 0; n < *lines; ++n) {
    sim::Rng rng(3, cam, n);
    r.render(scene, double(n) * rig.encoder_step_mm, rng, frame.data(), truth.data());
    stripe_rows(rig, frame.data(), rows);
  }
  return rows;
}

struct BlocksScan {
  std::vector<float> rows[2];
  std::vector<uint16_t> xray;
  int64_t lines = 0;
};

// Both cameras and the X-ray over a blocks scene, long enough for the X-ray plane.
inline BlocksScan scan_blocks(const LaneConfig& rig, const sim::CalibScene& scene,
                              const sim::XrayOptics& optics) {
  BlocksScan s;
  const sim::CameraRenderer c0(rig, 0), c1(rig, 1);
  const sim::CalibXrayRenderer xr(rig, optics);
  const int P = rig.xray.pixels;
  s.lines = int64_t((scene.end_b() + xr.plane_y(0, 0) + 40) / rig.encoder_step_mm);
  std::vector<uint8_t> frame(size_t(rig.frame_width) * rig.frame_height);
  std::vector<float> truth(rig.frame_width);
  s.xray.resize(size_t(s.lines) * P);
  for (int64_t n = 0; n < s.lines; ++n) {
    sim::Rng rng(9, n);
    const double at = double(n) * rig.encoder_step_mm;
    for (int cam = 0; cam < 2; ++cam) {
      (cam ? c1 : c0).render(scene, at, rng, frame.data(), truth.data());
      stripe_rows(rig, frame.data(), s.rows[cam]);
    }
    xr.render(scene, at, rng, &s.xray[size_t(n) * P]);
  }
  return s;
}

// Across the belt: how far the solved camera puts stripe points from where the true one
// does, mean and worst over a grid of the sensor (mm).
inline double across_belt_error(const CameraModel& solved, const CameraModel& truth,
                                double* worst) {
  double sum = 0;
  int n = 0;
  *worst = 0;
  for (double u = 40; u <= 600; u += 80)
    for (double v = 40; v <= 160; v += 40) {
      double xt = 0, xf = 0;
      if (!std::isfinite(plane_height(truth, u, v, &xt)) ||
          !std::isfinite(plane_height(solved, u, v, &xf)))
        continue;
      sum += std::abs(xf - xt), *worst = std::max(*worst, std::abs(xf - xt)), ++n;
    }
  return sum / std::max(1, n);
}

}  // namespace rangex::calib_test
