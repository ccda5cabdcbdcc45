// Paired samples for the scattering constants K1, K2 (Laser Range Imaging §5.4.2): for every column
// whose reference point lies on meat, the reference row (coated meat in the dissertation, the
// simulator's truth here) beside the plain centroid and asymmetry of the scattered stripe.
#pragma once
#include <cstdint>
#include <vector>

#include "calib/scatter_constants.h"
#include "core/stripe_params.h"

namespace rangex {

struct ScatterSamples {
  std::vector<float> reference, centroid, asym;
  size_t size() const { return reference.size(); }
  // K1, K2 from the samples gathered so far (fit_scatter_constants).
  ScatterFit fit() const;
};

// frames: `count` Mono8 frames (height x width); reference: count x width rows (NaN where
// none); on_meat: count x width flags, 1 where the reference point lies on the meat (the
// belt barely scatters). Appends the columns where both the stripe and the reference exist.
void add_scatter_samples(const uint8_t* frames, int count, int width, int height,
                         const StripeParams& params, const float* reference, const uint8_t* on_meat,
                         ScatterSamples& out);

}  // namespace rangex
