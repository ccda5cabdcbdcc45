// The laser light sheet: the plane n . p = offset in lane coordinates (x across the belt,
// y along the travel direction, z up from the belt surface, all in mm).
#pragma once
#include <optional>

#include "core/vec.h"

namespace rangex {

struct LaserPlane {
  Vec3 normal{0, 1, 0};  // unit length
  double offset_mm = 0;

  // Point where the ray meets the plane, or nothing when it runs parallel or points away.
  std::optional<Vec3> intersect(const Ray& ray) const {
    const double denom = normal.dot(ray.dir);
    if (std::abs(denom) < 1e-12) return std::nullopt;
    const double s = (offset_mm - normal.dot(ray.origin)) / denom;
    if (s <= 0) return std::nullopt;
    return ray.origin + ray.dir * s;
  }
};

}  // namespace rangex
