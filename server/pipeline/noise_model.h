// Signal-dependent X-ray noise in the log domain (Laser Range Imaging eq. 51 and 64): photon noise
// gives var(ln I) = a / I and electronic noise b / I^2, so sigma(I) = sqrt(a / I + b / I^2). a and
// b are estimated from a fillet's own residuals, binned by predicted intensity.
#pragma once
#include <cstddef>

namespace rangex {

struct NoiseModel {
  double a = 0, b = 0;
  // Near steep edges the pseudo-X-ray's own uncertainty: the laser-to-X-ray registration
  // and the edge's thickness (a shift of s pixels moves ln P by s |grad ln P|), so
  // var += c |grad ln P|^2 (c in px^2), fitted per fillet where the gradient is large.
  double c = 0;
  double sigma_ln(double intensity) const;
  double sigma_ln(double intensity, double grad2) const;
};

// predicted: pseudo-X-ray intensity per pixel; residual: ln I - ln P. Robust (MAD) variances
// per intensity bin, then non-negative least squares for a and b. Throws Error with fewer
// than 100 finite pixels.
NoiseModel estimate_noise_model(const float* predicted, const float* residual, size_t n);

// The gradient term of `m` from the pixels' squared gradients of ln P (per pixel^2): robust
// excess variance over a / I + b / I^2 in bins of the gradient, least squares through the
// origin; never below 1/12 px^2, the variance of an edge's place within its pixel.
double estimate_gradient_term(const NoiseModel& m, const float* predicted, const float* residual,
                              const float* grad2, size_t n);

}  // namespace rangex
