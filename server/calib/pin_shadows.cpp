#include "calib/pin_shadows.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>

#include "calib/block_covariance.h"
#include "calib/open_beam.h"
#include "core/error.h"

namespace rangex {

namespace {

// Transmission b (1 - [(1 - exp(-mu * chord)) * Gaussian(sigma)](u)) of a pin whose shadow
// has radius r px and centre c, averaged over the pixel's aperture; the chord is sampled
// finely and blurred analytically. b absorbs the open-beam estimate's error.
struct ShadowCost {
  std::vector<double> t;  // measured transmission, window pixels
  int u0;                 // pixel of t[0]
  double r;
  template <typename T>
  bool operator()(const T* p, T* res) const {
    const T& mu = p[0];
    const T& c = p[1];
    const T sigma = abs(p[2]) + T(0.05);
    constexpr int kS = 64, kAperture = 4;
    for (size_t i = 0; i < t.size(); ++i) {
      T sum = T(0);
      for (int a = 0; a < kAperture; ++a)
        for (int k = 0; k < kS; ++k) {
          const T u = T(double(u0 + int(i)) + (a + 0.5) / kAperture - 0.5);
          const double s = -r + (2 * r) * (k + 0.5) / kS;
          const double chord = 2 * std::sqrt(std::max(0.0, 1 - (s / r) * (s / r)));  // units of r
          const T absorbed = T(1) - exp(-mu * T(chord));
          // Gaussian of width sigma, integrated over the sub-sample of width 2r/kS.
          const T z = (u - c - T(s)) / sigma;
          sum += absorbed * exp(T(-0.5) * z * z) / (sigma * T(std::sqrt(2 * M_PI))) *
                 T(2 * r / kS / kAperture);
        }
      res[i] = p[3] * (T(1) - sum) - T(t[i]);
    }
    return true;
  }
};

}  // namespace

std::vector<PinShadow> measure_pin_shadows(const uint16_t* xray, int64_t lines, int pixels,
                                           const PinPhantom& ph, const FanBeam& nominal) {
  if (lines < 8) fail("the pin-phantom scan has only ", lines, " lines");
  // Every pin must fall on the detector with room for its shadow's window.
  for (size_t r = 0; r < ph.rows.size(); ++r)
    for (double x : ph.rows[r].x_mm) {
      const double u = fan_beam_pixel(nominal, x, ph.rows[r].z_mm);
      if (!(u >= 6 && u <= pixels - 7))
        fail("pin at x ", x, " mm in row ", r, " (z ", ph.rows[r].z_mm,
             " mm) is out of view: its shadow would fall at detector pixel ", u, " of ", pixels,
             "; move the phantom or drop the pin from its drawing");
    }
  const std::vector<double> open = open_beam(xray, lines, pixels);
  // Lines that carry pins: some pixel transmits less than 85 %.
  std::vector<uint8_t> dark(lines, 0);
  for (int64_t n = 0; n < lines; ++n) {
    int count = 0;
    for (int i = 0; i < pixels; ++i) count += xray[n * pixels + i] < 0.85 * open[i];
    dark[n] = count >= 2;
  }
  struct Run {
    int64_t a, b;
  };
  std::vector<Run> runs;
  for (int64_t n = 0; n < lines;) {
    if (!dark[n]) {
      ++n;
      continue;
    }
    int64_t e = n;
    while (e + 1 < lines && (dark[e + 1] || (e + 2 < lines && dark[e + 2]))) ++e;
    if (e - n + 1 >= 3) runs.push_back({n, e});
    n = e + 1;
  }
  if (runs.size() != ph.rows.size())
    fail("the pin-phantom scan shows ", runs.size(), " rows of pin shadows, the drawing has ",
         ph.rows.size(),
         (runs.size() < ph.rows.size() ? " (a row missed the X-ray plane?)"
                                       : " (something else lies on the belt?)"));
  std::vector<PinShadow> out;
  for (size_t r = 0; r < runs.size(); ++r) {
    const auto& row = ph.rows[r];
    // The middle half of the run: the pins fully inside the plane.
    const int64_t len = runs[r].b - runs[r].a + 1;
    const int64_t a = runs[r].a + len / 4, b = runs[r].b - len / 4;
    std::vector<double> t(pixels, 0);
    for (int64_t n = a; n <= b; ++n)
      for (int i = 0; i < pixels; ++i) t[i] += xray[n * pixels + i] / open[i];
    for (double& v : t) v /= double(b - a + 1);
    for (double x : row.x_mm) {
      const double up = fan_beam_pixel(nominal, x, row.z_mm);
      const double m =
          (nominal.source_z_mm - nominal.detector_z_mm) / (nominal.source_z_mm - row.z_mm);
      const double rpx = ph.radius_mm * m / nominal.pitch_mm;
      // Search +-4 px around the expectation for the darkest pixel, fit around it.
      const int guess = int(std::lround(up));
      int best = guess;
      for (int i = std::max(0, guess - 4); i <= std::min(pixels - 1, guess + 4); ++i)
        if (t[i] < t[best]) best = i;
      const std::string name = "row " + std::to_string(r) + " pin x " + std::to_string(int(x)) +
                               " mm z " + std::to_string(int(row.z_mm)) + " mm";
      if (t[best] > 0.95)
        fail("the shadow of ", name, " is not found near detector pixel ", int(up));
      const int w = int(std::ceil(rpx + 5));
      auto* cost = new ShadowCost;
      cost->u0 = std::max(0, best - w);
      for (int i = cost->u0; i <= std::min(pixels - 1, best + w); ++i) cost->t.push_back(t[i]);
      cost->r = rpx;
      double p[4] = {0.5, double(best), 1.0, 1.0};
      ceres::Problem problem;
      const int nres = int(cost->t.size());
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<ShadowCost, ceres::DYNAMIC, 4>(cost, nres), nullptr, p);
      ceres::Solver::Options so;
      so.linear_solver_type = ceres::DENSE_QR;
      so.max_num_iterations = 100;
      ceres::Solver::Summary sum;
      ceres::Solve(so, &problem, &sum);
      if (!sum.IsSolutionUsable() || std::abs(p[1] - best) > 3)
        fail("the shadow of ", name, " could not be fitted near pixel ", best);
      const std::vector<double> sds =
          block_stddev(problem, p, 4, 2 * sum.final_cost / std::max(1, nres - 4));
      PinShadow s;
      s.at = {name, x, row.z_mm, p[1]};
      s.sigma_px = std::abs(p[2]) + 0.05;
      s.sigma_std = sds.empty() ? 0 : sds[2];
      out.push_back(s);
    }
  }
  return out;
}

}  // namespace rangex
