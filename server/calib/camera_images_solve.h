// A camera's intrinsics and distortion from a folder of target images: the board is read
// from board.yaml beside them, the target found in each image, the camera solved, the
// lane's camera updated, and the uncertainty map and the residuals across the sensor
// drawn beside the calibration file.
#pragma once
#include <functional>
#include <optional>
#include <string>

#include "calib/camera_intrinsics.h"
#include "core/plant_config.h"

namespace rangex {

struct TargetBoard {
  int cols = 0, rows = 0;  // inner corners
  double square_mm = 0;
  std::optional<int> camera;  // the camera the images are of, when the drawing says
};
TargetBoard read_target_board(const std::string& dir);

struct CameraImagesOptions {
  int cam = 0;
  bool skip_unfound = false;  // an image without the target is left out (else an error)
  CameraSolveOptions solve;
  std::function<void(const std::string&)> warn;  // images left out, corners dropped
};

struct CameraImagesSolve {
  CameraFit fit;
  SolveReport report;
  size_t images = 0, with_target = 0;
};

// `out` is the calibration file the result goes to: the plots are written beside it
// (OUT.camN-uncertainty.png, OUT.camN-residuals.png).
CameraImagesSolve solve_camera_from_images(const std::string& dir, LaneConfig& lane,
                                           const CameraImagesOptions& opt, const std::string& out);

}  // namespace rangex
