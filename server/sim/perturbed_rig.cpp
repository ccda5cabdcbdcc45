#include "sim/perturbed_rig.h"

#include <cmath>

#include "sim/rng.h"

namespace rangex::sim {

SimulatedRig perturbed_rig(const LaneConfig& nominal, unsigned long seed) {
  Rng r(seed, 0x819, uint64_t(nominal.id));  // each lane its own rig
  SimulatedRig s;
  s.lane = nominal;
  const double d2r = M_PI / 180;
  for (auto& cam : s.lane.cameras) {
    const CameraModel& c = cam.model;
    Intrinsics k = c.intrinsics();
    k.fx *= 1 + r.uniform(-0.005, 0.005);
    k.fy *= 1 + r.uniform(-0.005, 0.005);
    // One draw per statement: the order of arguments' evaluation is unspecified.
    const double ax = r.uniform(-0.4, 0.4) * d2r;
    const double ay = r.uniform(-0.4, 0.4) * d2r;
    const double az = r.uniform(-0.3, 0.3) * d2r;
    const Mat3 R = rotation_xyz(ax, ay, az) * c.rotation();
    Vec3 centre = c.center();
    centre.x += r.uniform(-3, 3);
    centre.y += r.uniform(-3, 3);
    centre.z += r.uniform(-3, 3);
    cam.model = CameraModel(k, c.distortion(), R, (R * centre) * -1.0, c.width(), c.height());
  }
  FanBeam& x = s.lane.xray;
  x.source_x_mm += r.uniform(-3, 3);
  x.source_z_mm += r.uniform(-10, 10);
  x.first_pixel_x_mm += r.uniform(-1.5, 1.5);
  x.tilt_deg = r.uniform(-0.3, 0.3);
  // The line path registers whole lines; the plant simulator renders parallel planes.
  x.delay_lines = nominal.xray.delay_lines + r.integer(-2, 2);
  s.xray_plane_y_mm = nominal.laser.offset_mm + x.delay_lines * nominal.encoder_step_mm;
  s.alpha_rad = r.uniform(-0.3, 0.3) * d2r;
  s.beta_rad = r.uniform(-0.5, 0.5) * d2r;
  s.staircase_offset_mm = r.uniform(-1, 1);
  return s;
}

}  // namespace rangex::sim
