// One column of a laser stripe as the camera sees it (Laser Range Imaging eq. 13-14): a
// pixel-integrated Gaussian core plus a one-sided exponential scattering tail (convolved with the
// core), with multiplicative speckle. Adds onto the pixels already in the column.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sim/rng.h"

namespace rangex::sim {

struct StripeShape {
  double center;           // true row of the stripe centre
  double amplitude;        // DN at the core's peak
  double sigma;            // core standard deviation, px
  double tail;             // tail energy / core energy
  double tail_px;          // tail decay length, px
  int tail_sign;           // +1: tail toward larger rows
  double speckle;          // per-pixel multiplicative noise (std)
  double speckle_rho = 0;  // correlation of neighbouring pixels' speckle along the column
};

// The core and tail profiles of one (sigma, tail_px) tabulated finely, for rendering many
// columns fast (linear interpolation; relative error below 1e-5).
class StripeKernel {
 public:
  // One tabulated profile: values at x0 + i * kStep.
  struct Table {
    const double* v;
    size_t n;
    double x0;
    double at(double x) const {
      const double f = (x - x0) / kStep;
      if (f < 0 || f >= double(n - 1)) return 0.0;
      const size_t i = size_t(f);
      const double u = f - double(i);
      return v[i] + u * (v[i + 1] - v[i]);
    }
  };
  static constexpr double kStep = 1.0 / 512;  // px

  StripeKernel(double sigma, double tail_px);
  double sigma() const { return sigma_; }
  double tail_px() const { return tail_px_; }
  double core(double dy) const;  // pixel-integrated Gaussian of unit area
  double tail(double x) const;   // exponentially modified Gaussian density, tail toward +x
  Table core_table() const { return {core_.data(), core_.size(), core_x0_}; }
  Table tail_table() const { return {tail_.data(), tail_.size(), tail_x0_}; }

 private:
  double sigma_, tail_px_;
  double core_x0_, tail_x0_;
  std::vector<double> core_, tail_;
};

// column points at row 0 of the column; stride is the frame width. With a kernel whose
// sigma and tail_px match the shape, the tables are used; otherwise the exact functions.
void add_stripe(uint8_t* column, int height, int stride, const StripeShape& s, Rng& rng,
                const StripeKernel* kernel = nullptr);

}  // namespace rangex::sim
