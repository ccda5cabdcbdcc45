// Maximum-likelihood fit of the GEV regression of core/gev_model.h to per-fillet extremes.
#pragma once
#include <vector>

#include "core/gev_model.h"

namespace rangex {

struct ExtremeSample {
  double x = 0;  // the extreme (component_extreme of a statistic in one thickness band)
  double n = 0;  // pixels it was taken over
  double t = 0;  // their median thickness, mm
};

struct GevFitOptions {
  bool thickness = true;  // location and scale vary with the thickness
  // The shape, held where 40 maxima can say something. Never below 0: a bounded (Weibull)
  // tail fitted to a few dozen maxima claims that nothing lies beyond its end point, and
  // a false reject there would be "impossible"; Gumbel or heavier errs on the safe side.
  double xi_min = 0, xi_max = 0.6;
};

struct GevFit {
  GevModel model;
  double neg_log_likelihood = 0;
  bool converged = false;
};

// Throws Error with fewer than 10 samples.
GevFit fit_gev(const std::vector<ExtremeSample>& samples, const GevFitOptions& opt = {});

// The MLE of a location shift d of `model` (x ~ model moved by d) on `samples`, the other
// parameters held: how far a product's extremes have drifted from what was learned.
double fit_location_shift(const GevModel& model, const std::vector<ExtremeSample>& samples);

}  // namespace rangex
