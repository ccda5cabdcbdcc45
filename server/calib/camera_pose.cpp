#include "calib/camera_pose.h"

#include <ceres/rotation.h>

namespace rangex {

CameraModel posed_camera(const CameraModel& start, const double* p) {
  double dR[9];
  ceres::AngleAxisToRotationMatrix(p, ceres::RowMajorAdapter3x3(dR));
  Mat3 d;
  for (int i = 0; i < 9; ++i) d.m[i] = dR[i];
  const Mat3 R = d * start.rotation();
  const Vec3 c{p[3], p[4], p[5]};
  return CameraModel(start.intrinsics(), start.distortion(), R, (R * c) * -1.0, start.width(),
                     start.height());
}

void pose_parameters(const CameraModel& start, double* p) {
  const Vec3 c = start.center();
  p[0] = p[1] = p[2] = 0;
  p[3] = c.x, p[4] = c.y, p[5] = c.z;
}

}  // namespace rangex
