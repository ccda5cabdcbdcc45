// Length of an X-ray path through meat whose upper surface is a height profile sampled on a
// uniform x grid (linear between samples, zero outside the grid). The meat fills
// 0 <= z <= h(x); the ray runs from the detector point (xd, zd) to the source (xs, zs).
// Eq. 39-40 of the dissertation (T = d / cos theta) is the special case of a flat top; here
// the ray is followed cell by cell, so a slanted ray through a sloped surface is exact.
#pragma once
#include <cstdint>

namespace rangex {

struct ProfileGrid {
  const float* height;   // n samples, mm
  const uint8_t* valid;  // n flags, or nullptr when every sample is valid
  int n;
  double x0_mm;     // x of sample 0
  double pitch_mm;  // sample spacing
  float max_height_mm;
};

struct PathResult {
  double length_mm = 0;
  bool valid = true;  // false when the ray crossed an invalid sample inside the meat range
};

PathResult ray_path_length(const ProfileGrid& g, double xd, double zd, double xs, double zs);

// One step of the walk: the cell of the grid (x0, pitch) the ray from (xd, zd) with dx/dz
// `slope` is in at height z, and the height where it leaves it (at most ztop).
struct RayStep {
  int cell;
  double zexit;
};
RayStep ray_step(double z, double xd, double zd, double slope, double x0_mm, double pitch_mm,
                 double ztop);

// Length of [a, b] where the linear function with end values fa, fb is positive.
double positive_span(double a, double b, double fa, double fb);

// A segment of no length only crosses a cell boundary: there is no meat in it to sample.
constexpr double kMinRaySegmentMm = 1e-6;

}  // namespace rangex
