// Planar calibration target (a checkerboard) seen by one camera with the laser off (seed
// §6.3.2.2, eq. 30): random poses that keep the whole board in view, and full Mono8 frames
// rendered through the camera's exact model (distortion included) with the true corner
// positions beside them.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "core/camera_model.h"
#include "sim/rng.h"

namespace rangex::sim {

struct TargetBoard {
  int cols = 12, rows = 6;  // inner corners
  double square_mm = 8.0;   // printed squares
  // Corner (i, j) lies at (i * square, j * square, 0) on the board, row-major.
  std::vector<Vec3> corners() const;
};

struct TargetPose {
  Mat3 R;  // board to camera: Xc = R * Xb + t
  Vec3 t;
};

struct TargetRenderParams {
  double black = 30, white = 210, background = 12;  // DN
  double noise = 2.0;                               // DN, read noise
  int supersample = 8;                              // per axis, for anti-aliased edges
  double optics_blur_px = 0.7;                      // Gaussian sigma of lens and sensor
};

// n poses at 450..700 mm, tilted up to 40 degrees, spread across the sensor; every corner
// and the board's white margin stay inside the frame.
std::vector<TargetPose> random_target_poses(const CameraModel& cam, const TargetBoard& board, int n,
                                            uint64_t seed);

class TargetRenderer {
 public:
  TargetRenderer(const CameraModel& cam, TargetBoard board, TargetRenderParams p = {});
  // frame: width x height Mono8; truth: the corners' true distorted pixel positions.
  void render(const TargetPose& pose, Rng& rng, uint8_t* frame, std::vector<Vec2>* truth) const;

 private:
  const CameraModel& cam_;
  TargetBoard board_;
  TargetRenderParams p_;
  // Per pixel: the undistorted normalised ray through its centre and its derivatives by
  // u and v, so sub-samples follow the lens model to second order (built once).
  std::vector<std::array<double, 6>> rays_;
};

}  // namespace rangex::sim
