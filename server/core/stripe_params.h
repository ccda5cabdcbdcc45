// Stripe extraction settings and the per-camera scattering constants (Laser Range Imaging ch. 5).
#pragma once
#include <string>
#include <string_view>

#include "shared/stripe_methods.h"

namespace rangex {

// The numbers are the kernels' (kernels/shared/stripe_methods.h): a lane table carries them.
enum class StripeMethod {
  kCentroid = METHOD_CENTROID,    // eq. 15 with g = intensity above threshold
  kSquared = METHOD_SQUARED,      // eq. 15 with g squared
  kBinary = METHOD_BINARY,        // midpoint of the half-maximum crossings (interpolated)
  kGaussian3 = METHOD_GAUSSIAN3,  // 3-point Gaussian (log-parabola) peak
  kParabola = METHOD_PARABOLA,    // 3-point parabola peak
  kShifted = METHOD_SHIFTED,      // eq. 18: centroid + K1
  kModified = METHOD_MODIFIED,    // eq. 19: centroid + offset + K2 * asymmetry (stripe_extract.h)
};

// Parses the names used on the command line and in plant.yaml; throws Error naming the
// accepted names for anything else.
StripeMethod parse_stripe_method(std::string_view name);
std::string_view stripe_method_name(StripeMethod m);

struct ScatterConstants {
  double k1 = 0;         // shifted centroid offset, px (eq. 18)
  double k2 = 0;         // modified centroid gain on the asymmetry, px (eq. 19)
  double k2_offset = 0;  // modified centroid constant offset, px
};

struct StripeParams {
  StripeMethod method = StripeMethod::kModified;
  int min_peak = 40;           // DN: a column whose maximum is lower has no stripe
  double threshold_rel = 0.2;  // window threshold as a fraction of the peak
  int max_width = 40;          // px: wider windows are glare, not a stripe
};

}  // namespace rangex
