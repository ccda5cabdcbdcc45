// Calibration objects on the belt (Laser Range Imaging §6.4): CNC blocks (the staircase of Table 5,
// the registration blocks of §6.4.3) and steel pins held across the fan beam (Figure 27), in the
// object coordinates of LaneScene (x across, b along the belt). Their surfaces feed the camera
// renderer; their attenuation feeds CalibXrayRenderer.
#pragma once
#include <cmath>
#include <vector>

#include "core/vec.h"

namespace rangex::sim {

struct CalibBox {
  // yaw: turned about the vertical through its centre (a block set askew). Its cosine and sine
  // are taken once here: every ray and surface sample of a scan turns into the box's frame.
  CalibBox(double x0, double x1, double b0, double b1, double z0, double z1, double yaw = 0)
      : x0(x0),
        x1(x1),
        b0(b0),
        b1(b1),
        z0(z0),
        z1(z1),
        cos_yaw_(std::cos(yaw)),
        sin_yaw_(std::sin(yaw)) {}
  double x0, x1, b0, b1, z0, z1;  // mm, in the box's own frame
  double sin_yaw() const { return sin_yaw_; }
  // Object point (x, b) in the box's own frame.
  void local(double x, double b, double& lx, double& lb) const {
    const double cx = 0.5 * (x0 + x1), cb = 0.5 * (b0 + b1);
    const double c = cos_yaw_, s = sin_yaw_;
    lx = cx + c * (x - cx) + s * (b - cb);
    lb = cb - s * (x - cx) + c * (b - cb);
  }
  bool covers(double x, double b) const {
    double lx, lb;
    local(x, b, lx, lb);
    return lx >= x0 && lx < x1 && lb >= b0 && lb < b1;
  }
  // Whether the turned footprint may reach into [x_lo, x_hi] x [b_lo, b_hi] (object
  // coordinates): its bounding rectangle, 1 mm to spare for rounding, does. false: it cannot.
  bool may_reach(double x_lo, double x_hi, double b_lo, double b_hi) const {
    const double hx = 0.5 * (x1 - x0), hb = 0.5 * (b1 - b0);
    const double c = std::abs(cos_yaw_), s = std::abs(sin_yaw_);
    const double rx = c * hx + s * hb + 1, rb = s * hx + c * hb + 1;
    const double cx = 0.5 * (x0 + x1), cb = 0.5 * (b0 + b1);
    return cx + rx >= x_lo && cx - rx <= x_hi && cb + rb >= b_lo && cb - rb <= b_hi;
  }
  double mu_per_mm = 0.02;  // POM-like plastic at the X-ray's energy, per mm of path

 private:
  double cos_yaw_, sin_yaw_;
};

// A steel pin running along the belt: its cross-section is a circle in the fan's plane.
struct CalibPin {
  double x, z, radius, b0, b1;  // mm
  double mu_per_mm = 0.5;       // steel
};

class CalibScene {
 public:
  std::vector<CalibBox> boxes;
  std::vector<CalibPin> pins;  // held in a transparent fixture: invisible to the laser

  float height(double x, double b) const;         // highest box top at (x, b), 0 on the belt
  void slice(double b, float* out, int n) const;  // as LaneScene::slice, box-filtered
  float max_height(double b_lo, double b_hi) const;
  // Whether height is 0 everywhere in [x_lo, x_hi] x [b_lo, b_hi]: no box reaches it.
  bool bare(double x_lo, double x_hi, double b_lo, double b_hi) const;
  bool is_meat(const Vec3&) const { return false; }  // machined metal barely scatters
  double scatter_scale(const Vec3&, double) const { return 1; }
  double end_b() const;
};

}  // namespace rangex::sim
