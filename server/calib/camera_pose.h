// A camera pose as a small change from a starting model, the parameter block of the solvers
// that move a camera (staircase, registration): p[0..2] an angle-axis rotation applied after
// the start's rotation, p[3..5] the camera centre (mm). Intrinsics stay as calibrated.
#pragma once
#include "core/camera_model.h"

namespace rangex {

CameraModel posed_camera(const CameraModel& start, const double* p);

// p for `start` itself: no rotation, the start's centre.
void pose_parameters(const CameraModel& start, double* p);

}  // namespace rangex
