#include "calib/scatter_samples.h"

#include <cmath>

#include "pipeline/stripe_extract.h"

namespace rangex {

ScatterFit ScatterSamples::fit() const {
  return fit_scatter_constants(reference.data(), centroid.data(), asym.data(), size());
}

void add_scatter_samples(const uint8_t* frames, int count, int width, int height,
                         const StripeParams& params, const float* reference, const uint8_t* on_meat,
                         ScatterSamples& out) {
  // The constants correct the plain centroid: measure it, whatever method the lane runs.
  StripeSlot slot{params, {}};
  slot.params.method = StripeMethod::kCentroid;
  const std::vector<int> slots(size_t(count), 0);
  StripeOutput so;
  extract_stripes(frames, count, width, height, slots.data(), &slot, so);
  for (size_t i = 0; i < size_t(count) * width; ++i) {
    if (!so.valid[i] || !on_meat[i] || !std::isfinite(reference[i])) continue;
    out.reference.push_back(reference[i]);
    out.centroid.push_back(so.centroid[i]);
    out.asym.push_back(so.asym[i]);
  }
}

}  // namespace rangex
