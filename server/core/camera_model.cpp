#include "core/camera_model.h"

#include <cmath>

namespace rangex {

CameraModel::CameraModel(Intrinsics k, Distortion d, Mat3 R, Vec3 t, int width, int height)
    : k_(k), d_(d), R_(R), t_(t), width_(width), height_(height) {}

Vec2 CameraModel::distort(const Vec2& p) const {
  const double r2 = p.x * p.x + p.y * p.y;
  const double radial = 1 + r2 * (d_.k1 + r2 * (d_.k2 + r2 * d_.k3));
  return {p.x * radial + 2 * d_.p1 * p.x * p.y + d_.p2 * (r2 + 2 * p.x * p.x),
          p.y * radial + d_.p1 * (r2 + 2 * p.y * p.y) + 2 * d_.p2 * p.x * p.y};
}

Vec2 CameraModel::undistort(const Vec2& target) const {
  // Newton on F(p) = distort(p) - target with the analytic Jacobian; starts at the target,
  // which is close because the distortion is small over the sensor.
  Vec2 p = target;
  for (int it = 0; it < 50; ++it) {
    const double x = p.x, y = p.y, r2 = x * x + y * y;
    const double radial = 1 + r2 * (d_.k1 + r2 * (d_.k2 + r2 * d_.k3));
    const double dradial = d_.k1 + r2 * (2 * d_.k2 + 3 * d_.k3 * r2);  // d radial / d r2
    const Vec2 f = distort(p);
    const double ex = f.x - target.x, ey = f.y - target.y;
    const double j00 = radial + x * dradial * 2 * x + 2 * d_.p1 * y + d_.p2 * 6 * x;
    const double j01 = x * dradial * 2 * y + 2 * d_.p1 * x + d_.p2 * 2 * y;
    const double j10 = y * dradial * 2 * x + d_.p1 * 2 * x + 2 * d_.p2 * y;
    const double j11 = radial + y * dradial * 2 * y + d_.p1 * 6 * y + 2 * d_.p2 * x;
    const double det = j00 * j11 - j01 * j10;
    const double dx = (j11 * ex - j01 * ey) / det, dy = (j00 * ey - j10 * ex) / det;
    p.x -= dx;
    p.y -= dy;
    if (std::abs(dx) + std::abs(dy) < 1e-15) break;
  }
  return p;
}

Vec2 CameraModel::pixel_to_normalized(const Vec2& px) const {
  const double y = (px.y - k_.cy) / k_.fy;
  const double x = (px.x - k_.cx) / k_.fx - k_.skew * y;
  return {x, y};
}

Vec2 CameraModel::normalized_to_pixel(const Vec2& xn) const {
  return {k_.fx * (xn.x + k_.skew * xn.y) + k_.cx, k_.fy * xn.y + k_.cy};
}

Vec2 CameraModel::project(const Vec3& w) const {
  const Vec3 c = R_ * w + t_;
  return normalized_to_pixel(distort({c.x / c.z, c.y / c.z}));
}

Ray CameraModel::pixel_ray(const Vec2& px) const {
  const Vec2 ideal = undistort(pixel_to_normalized(px));
  const Vec3 dir_cam{ideal.x, ideal.y, 1.0};
  return {center(), (R_.transposed() * dir_cam).normalized()};
}

Vec3 CameraModel::center() const {
  return (R_.transposed() * t_) * -1.0;
}

}  // namespace rangex
