// Signal-dependent X-ray noise in the log domain (seed eq. 51 and 64): photon noise gives
// var(ln I) = a / I and electronic noise b / I^2, so sigma(I) = sqrt(a / I + b / I^2).
// a and b are estimated from a fillet's own residuals, binned by predicted intensity.
#pragma once
#include <cstddef>

namespace rangex {

struct NoiseModel {
  double a = 0, b = 0;
  double sigma_ln(double intensity) const;
};

// predicted: pseudo-X-ray intensity per pixel; residual: ln I - ln P. Robust (MAD) variances
// per intensity bin, then non-negative least squares for a and b. Throws Error with fewer
// than 100 finite pixels.
NoiseModel estimate_noise_model(const float* predicted, const float* residual, size_t n);

}  // namespace rangex
