// The plant simulator: per lane a scene of fillets, two virtual cameras and a virtual X-ray
// detector, rendered line by line from a seed (the same seed gives the same bytes), and a
// writer that stores it all as a recording with truth/.
#pragma once
#include <cstdint>
#include <functional>
#include <string>

#include "core/plant_config.h"
#include "sim/camera_renderer.h"
#include "sim/lane_scene.h"
#include "sim/plant_physics.h"
#include "sim/xray_renderer.h"

namespace rangex::sim {

struct SimulationParams {
  int lanes = 4;
  uint64_t seed = 1;
  SceneParams scene;
  CameraRenderParams camera;
  XrayRenderParams xray;
  int64_t encoder_start = 1000;
  // The plant's physics; it sets the scene's and the camera's fields it names (the
  // defaults are theirs).
  PlantPhysics physics;
};

// The scene and camera parameters with the physics' parts applied.
SceneParams scene_params(const SimulationParams& p);
CameraRenderParams camera_params(const SimulationParams& p);

class LaneSimulator {
 public:
  LaneSimulator(const LaneConfig& lane, const SimulationParams& p);

  int64_t lines() const { return lines_; }  // enough to carry every fillet past both planes
  // Lines lost on the way (the plant's dropped_line_rate): never delivered.
  bool dropped(int64_t n) const;
  // Line n of the lane; truth pointers may be null. xray_high: a lane of two energies'
  // high line (`xray` is then the low one); null for a lane of one.
  void render(int64_t n, uint8_t* cam0, uint8_t* cam1, uint16_t* xray, float* truth_row0,
              float* truth_row1, float* truth_thickness, uint16_t* xray_high = nullptr) const;
  int energies() const { return lane_.xray.energies; }
  int64_t encoder(int64_t n) const { return encoder_start_ + n; }
  const LaneScene& scene() const { return scene_; }
  // CSV of the bone fragments with their belt positions and X-ray line.
  std::string fragments_csv() const;
  std::string fillets_csv() const;

 private:
  LaneConfig lane_;
  uint64_t seed_;
  LaneScene scene_;
  CameraRenderer cam0_, cam1_;
  XrayRenderer xray_;
  int64_t lines_ = 0;
  int64_t encoder_start_;
  double dropped_rate_ = 0, jitter_mm_ = 0;
};

using Progress = std::function<void(int64_t done, int64_t total)>;

// Simulates every lane of `plant` (the first p.lanes lanes) and writes a recording.
void simulate_recording(const PlantConfig& plant, const SimulationParams& p, const std::string& dir,
                        const Progress& progress = {});

}  // namespace rangex::sim
