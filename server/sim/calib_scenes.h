// Calibration scans from the simulator: the machined objects of core/calibration_objects.h
// put on a lane's belt and recorded through a (true) rig that may differ from plant.yaml,
// with the true rig and optics written to truth/ beside the recording.
#pragma once
#include <cstdint>
#include <functional>
#include <string>

#include "core/calibration_objects.h"
#include "core/lane_config.h"
#include "sim/calib_objects.h"
#include "sim/calib_xray_renderer.h"
#include "sim/camera_renderer.h"

namespace rangex::sim {

CalibScene staircase_scene(const Staircase& s);
CalibScene pin_phantom_scene(const PinPhantom& p);
// Blocks at random places across the lane (|x| within half_width_mm), each at least
// gap_mm behind the previous one.
CalibScene block_scene(const BlockSet& b, uint64_t seed, double half_width_mm = 70);

struct CalibScanParams {
  uint64_t seed = 1;
  XrayOptics optics;
  CameraRenderParams camera;
  XrayRenderParams xray;
  bool cameras = true;  // the pin phantom needs the X-ray only
  int64_t encoder_start = 1000;
  double trail_mm = 30;  // belt after the scene's end
};

// Writes a one-lane recording of `scene` seen through `rig` (lane id, frame size, geometry)
// into dir; truth/ holds rig.yaml (the true calibration) and optics.yaml.
void simulate_calib_scan(const LaneConfig& rig, const CalibScene& scene, const CalibScanParams& p,
                         const std::string& dir,
                         const std::function<void(int64_t, int64_t)>& progress = {});

}  // namespace rangex::sim
