#include "calib/xray_blur.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace rangex {

XrayBlurFit fit_xray_blur(const std::vector<PinShadow>& pins, const FanBeam& g) {
  if (pins.size() < 4) fail("too few pin shadows for the blur: ", pins.size());
  const int n = int(pins.size());
  Eigen::MatrixXd A(n, 2);
  Eigen::VectorXd y(n), w(n);
  double zmin = 1e9, zmax = -1e9;
  for (int i = 0; i < n; ++i) {
    const PinShadow& p = pins[i];
    const double m = (p.at.z_mm - g.detector_z_mm) / (g.source_z_mm - p.at.z_mm) / g.pitch_mm;
    A(i, 0) = 1;
    A(i, 1) = m * m;
    y(i) = p.sigma_px * p.sigma_px;
    // var(sigma^2) = (2 sigma sd)^2; a floor keeps one over-confident pin from ruling.
    const double sd = std::max(2 * p.sigma_px * p.sigma_std, 1e-4);
    w(i) = 1 / sd;
    zmin = std::min(zmin, p.at.z_mm);
    zmax = std::max(zmax, p.at.z_mm);
  }
  if (zmax - zmin < 5)
    fail("the pins span only ", zmax - zmin, " mm of height: the focal spot is undetermined");
  const Eigen::MatrixXd Aw = w.asDiagonal() * A;
  const Eigen::VectorXd yw = w.asDiagonal() * y;
  const Eigen::Vector2d x = Aw.colPivHouseholderQr().solve(yw);
  const Eigen::VectorXd r = yw - Aw * x;
  const double s2 = r.squaredNorm() / std::max(1, n - 2);
  const Eigen::Matrix2d C = (Aw.transpose() * Aw).inverse() * s2;
  XrayBlurFit f;
  const double a = std::max(0.0, x(0)), b = std::max(0.0, x(1));
  f.detector_sigma_px = std::sqrt(a);
  f.focal_spot_sigma_mm = std::sqrt(b);
  // d sqrt(a) = da / (2 sqrt(a)).
  f.detector_std = std::sqrt(C(0, 0)) / (2 * std::max(f.detector_sigma_px, 1e-6));
  f.focal_spot_std = std::sqrt(C(1, 1)) / (2 * std::max(f.focal_spot_sigma_mm, 1e-3));
  double ss = 0;
  for (int i = 0; i < n; ++i) {
    const double model = std::sqrt(std::max(0.0, a + b * A(i, 1)));
    ss += std::pow(pins[i].sigma_px - model, 2);
  }
  f.rms_px = std::sqrt(ss / n);
  return f;
}

SolveReport XrayBlurFit::report(const std::string& subject) const {
  SolveReport r;
  r.solver = "blur";
  r.subject = subject;
  r.parameters = {{"detector_sigma_px", detector_sigma_px, detector_std, "px"},
                  {"focal_spot_sigma_mm", focal_spot_sigma_mm, focal_spot_std, "mm"}};
  r.figures = {{"width_rms_px", rms_px}};
  return r;
}

}  // namespace rangex
