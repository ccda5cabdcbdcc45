// Maximum-likelihood fit of the GEV regression of core/gev_model.h to per-fillet extremes.
#pragma once
#include <cmath>
#include <vector>

#include "core/gev_model.h"

namespace rangex {

struct ExtremeSample {
  double x = 0;  // the extreme (component_extreme of a statistic in one thickness band)
  double n = 0;  // pixels it was taken over
  double t = 0;  // their median thickness, mm
  // Seen only because it stayed below this (a passed fillet's extreme under a threshold):
  // the likelihood is truncated there. Infinity: not truncated.
  double upper = HUGE_VAL;
  // Seen only above this: the likelihood is truncated here too, and a sample below is left
  // out. A small band's extreme far in the Gumbel's thin lower tail otherwise outweighs a
  // hundred others, and the lower tail says nothing of false rejects. -Infinity: not
  // truncated.
  double lower = -HUGE_VAL;
  // At or below this only that it lay there counts (F(censor), left-censored): a fit to the
  // upper tail, which the false rejects live in, that the bulk cannot bend. -Infinity: not
  // censored.
  double censor = -HUGE_VAL;
};

struct GevFitOptions {
  // The shape, held where 40 maxima can say something. Never below 0: a bounded (Weibull)
  // tail fitted to a few dozen maxima claims that nothing lies beyond its end point, and
  // a false reject there would be "impossible"; Gumbel or heavier errs on the safe side.
  double xi_min = 0, xi_max = 0.6;
  // > 0: fitted to the upper tail, each extreme at or below the whole fit's quantile at this
  // probability (at its own pixels and thickness) left-censored there (ExtremeSample::censor).
  double tail_from = 0;
};

struct GevFit {
  GevModel model;
  bool converged = false;
  // A tail fit (GevFitOptions::tail_from > 0): the fit to every extreme, whose tail_from
  // quantile censored them, and that probability; tail_from 0 otherwise.
  GevModel whole;
  double tail_from = 0;
};

// Where a tail fit censors an extreme: the whole fit's `tail_from` quantile at the extreme's
// own pixels and thickness; -Infinity without a tail fit (tail_from 0). Learning, its QQ and
// KS, and the drift monitor all censor there.
inline double tail_level(const GevModel& whole, double tail_from, double n, double t) {
  return tail_from > 0 ? whole.quantile(tail_from, n, t) : -HUGE_VAL;
}

// Throws Error with fewer than 10 samples. Samples with a finite `upper` count truncated
// there (a fit to the extremes below a level, robust to what lies above it).
GevFit fit_gev(const std::vector<ExtremeSample>& samples, const GevFitOptions& opt = {});

// The MLE of a location shift d of `model` (x ~ model moved by d) on `samples`, the other
// parameters held: how far a product's extremes have drifted from what was learned. Samples
// with a finite `upper` count with the truncated density f(x) / F(upper): a lane sees the
// extremes of the fillets it passed, and a rougher product's come close to its thresholds.
// Samples under a finite `lower` are left out, the others truncated there.
double fit_location_shift(const GevModel& model, const std::vector<ExtremeSample>& samples);

// The same model refitted to recent samples in its location, scale and shape (the
// covariates' slopes held): a product whose tail grew heavier, not only higher (specks of
// gristle the median does not see), shows in scale and shape. Truncated like
// fit_location_shift. The location shift alone stands unless the scale and shape improve the
// likelihood beyond chance (a likelihood-ratio test, 2 degrees of freedom, 1 %): the free refit
// over-reads a tail that truncation hides.
// `location_shift`, when given, receives that location shift (fit_location_shift's).
GevModel refit_drifted(const GevModel& model, const std::vector<ExtremeSample>& samples,
                       double* location_shift = nullptr, const GevFitOptions& opt = {});

}  // namespace rangex
