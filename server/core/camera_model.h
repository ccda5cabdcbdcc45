// Pinhole camera with OpenCV's distortion convention (k1, k2, p1, p2, k3) and a skew term
// as in Bouguet's toolbox (the dissertation's appendices D and E come from it).
#pragma once
#include "core/vec.h"

namespace rangex {

struct Intrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0, skew = 0;  // skew: u = fx*(x + skew*y) + cx
};

struct Distortion {
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
};

class CameraModel {
 public:
  CameraModel() = default;
  // R, t map world to camera coordinates: Xc = R * Xw + t.
  CameraModel(Intrinsics k, Distortion d, Mat3 R, Vec3 t, int width, int height);

  // World point to distorted pixel (u, v); pixel centres are at integer coordinates.
  Vec2 project(const Vec3& world) const;
  // Ideal normalised image point to distorted normalised point (the forward lens model).
  Vec2 distort(const Vec2& ideal) const;
  // Inverse of distort(), by Newton iteration to 1e-14.
  Vec2 undistort(const Vec2& distorted) const;
  // Distorted pixel to distorted normalised coordinates (inverse of the intrinsic matrix).
  Vec2 pixel_to_normalized(const Vec2& px) const;
  Vec2 normalized_to_pixel(const Vec2& xn) const;
  // Ray in world coordinates through the centre of a (distorted) pixel position.
  Ray pixel_ray(const Vec2& px) const;
  Vec3 center() const;  // camera centre in world coordinates

  const Intrinsics& intrinsics() const { return k_; }
  const Distortion& distortion() const { return d_; }
  const Mat3& rotation() const { return R_; }
  const Vec3& translation() const { return t_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  Intrinsics k_;
  Distortion d_;
  Mat3 R_;
  Vec3 t_;
  int width_ = 0, height_ = 0;
};

}  // namespace rangex
