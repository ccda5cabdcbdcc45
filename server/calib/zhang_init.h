// Zhang's closed-form start for a planar target (Laser Range Imaging eqs. 30-34): a homography per
// view, the intrinsic matrix from the image of the absolute conic, then each view's pose with its
// rotation made orthonormal. Lens distortion is ignored here; the refinement adds it.
#pragma once
#include <vector>

#include "core/camera_model.h"

namespace rangex {

struct PlanarView {
  std::vector<Vec3> board;   // z = 0 on the target
  std::vector<Vec2> pixels;  // detected corners, same order
};

struct ZhangStart {
  Intrinsics intrinsics;
  std::vector<Mat3> R;  // board to camera, one per view
  std::vector<Vec3> t;
};

// Throws Error (naming the problem) for fewer than 3 views, a view with fewer than 4
// corners, or a pose set that leaves the intrinsics undetermined (parallel boards).
ZhangStart zhang_initialise(const std::vector<PlanarView>& views);

}  // namespace rangex
