// Scattering constants K1 and K2 (Laser Range Imaging §5.4.2) from paired profiles: the reference
// row of each column (coated meat in the dissertation, the simulator's truth here) beside the plain
// centroid and asymmetry measured on the scattered stripe.
#pragma once
#include <cstddef>

#include "core/stripe_params.h"

namespace rangex {

struct ScatterFit {
  ScatterConstants constants;
  size_t samples = 0;
  double centroid_mae_px = 0;  // |C - reference| before correction
  double shifted_mae_px = 0;   // after eq. 18
  double modified_mae_px = 0;  // after eq. 19
};

// reference, centroid, asym: n samples each; NaN references are skipped. Throws Error when
// fewer than 10 usable samples remain or the asymmetry does not vary.
ScatterFit fit_scatter_constants(const float* reference, const float* centroid, const float* asym,
                                 size_t n);

}  // namespace rangex
