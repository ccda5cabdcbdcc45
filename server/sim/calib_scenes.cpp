#include "sim/calib_scenes.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "core/plant_config.h"
#include "core/recording.h"
#include "sim/rng.h"

namespace rangex::sim {

CalibScene staircase_scene(const Staircase& s) {
  CalibScene sc;
  for (size_t i = 0; i < s.heights_mm.size(); ++i) {
    const double x0 = s.x0_mm + s.step_width_mm * double(i);
    sc.boxes.push_back(
        {x0, x0 + s.step_width_mm, s.lead_in_mm, s.lead_in_mm + s.length_mm, 0, s.heights_mm[i]});
  }
  return sc;
}

CalibScene pin_phantom_scene(const PinPhantom& p) {
  CalibScene sc;
  for (size_t r = 0; r < p.rows.size(); ++r) {
    const double b0 = p.lead_in_mm + p.row_pitch_mm * double(r);
    for (double x : p.rows[r].x_mm)
      sc.pins.push_back({x, p.rows[r].z_mm, p.radius_mm, b0, b0 + p.pin_length_mm});
  }
  return sc;
}

CalibScene block_scene(const BlockSet& b, uint64_t seed, double half_width_mm) {
  Rng rng(seed, 0xb10c);
  CalibScene sc;
  double at = b.lead_in_mm;
  for (const auto& k : b.blocks) {
    const double room = std::max(0.0, 2 * half_width_mm - k.width_mm);
    const double x0 = -half_width_mm + rng.uniform(0, room);
    const double b0 = at + rng.uniform(0, 10);
    // Set askew by 4..10 degrees either way: a wall then crosses a plane over several lines
    // across the belt, which makes its crossing measurable to a fraction of a line.
    const double yaw = (rng.chance(0.5) ? 1 : -1) * rng.uniform(4, 10) * M_PI / 180;
    sc.boxes.push_back({x0, x0 + k.width_mm, b0, b0 + k.length_mm, 0, k.height_mm, yaw});
    at = b0 + k.length_mm + k.width_mm * std::abs(std::sin(yaw)) + b.gap_mm;
  }
  return sc;
}

void simulate_calib_scan(const LaneConfig& rig, const CalibScene& scene, const CalibScanParams& p,
                         const std::string& dir,
                         const std::function<void(int64_t, int64_t)>& progress) {
  CalibXrayRenderer xr(rig, p.optics, p.xray);
  // Long enough for the scene's end to pass the later of the two planes.
  const double far_plane = std::max(0.0, xr.plane_y(0, 0)) + 5;
  const int64_t lines =
      int64_t(std::ceil((scene.end_b() + far_plane + p.trail_mm) / rig.encoder_step_mm));
  RecordingInfo info;
  info.lanes = {rig.id};
  info.width = rig.frame_width;
  info.height = rig.frame_height;
  info.xray_pixels = rig.xray.pixels;
  info.encoder_step_mm = rig.encoder_step_mm;
  info.calibration_id = "calibration-scan";
  info.has_truth = true;
  info.seed = p.seed;
  RecordingWriter w(dir, info);
  CameraRenderer cam0(rig, 0, p.camera), cam1(rig, 1, p.camera);
  const size_t frame = size_t(rig.frame_width) * rig.frame_height;
  std::vector<uint8_t> f0(frame, 0), f1(frame, 0);
  std::vector<uint16_t> x(rig.xray.pixels);
  std::vector<float> t0(rig.frame_width), t1(rig.frame_width);
  for (int64_t n = 0; n < lines; ++n) {
    const double s = double(n) * rig.encoder_step_mm;
    Rng rng(p.seed, uint64_t(rig.id), uint64_t(n), 0xca1);
    if (p.cameras) {
      cam0.render(scene, s, rng, f0.data(), t0.data());
      cam1.render(scene, s, rng, f1.data(), t1.data());
      w.append_truth(rig.id, "stripe_cam0.f32", t0.data(), t0.size() * sizeof(float));
      w.append_truth(rig.id, "stripe_cam1.f32", t1.data(), t1.size() * sizeof(float));
    }
    xr.render(scene, s, rng, x.data());
    w.append(rig.id, {f0.data(), f1.data(), x.data(), p.encoder_start + n});
    if (progress && (n % 64 == 0 || n + 1 == lines)) progress(n + 1, lines);
  }
  w.write_truth_text(rig.id, "rig.yaml", lane_calibration_yaml(rig));
  std::ostringstream o;
  o.precision(12);
  o << "optics:\n  focal_spot_sigma_mm: " << p.optics.focal_spot_sigma_mm
    << "\n  detector_sigma_px: " << p.optics.detector_sigma_px
    << "\n  plane_y_mm: " << xr.plane_y(0, 0) << "\n  alpha_rad: " << p.optics.alpha_rad
    << "\n  beta_rad: " << p.optics.beta_rad << "\n";
  w.write_truth_text(rig.id, "optics.yaml", o.str());
  w.close();
}

}  // namespace rangex::sim
