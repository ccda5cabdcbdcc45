// Robust straight-line fit ln I = b0 + b1 * T by iteratively reweighted least squares with
// Tukey's biweight (Laser Range Imaging eq. 66-70), following statsmodels' RLM(...,
// M=TukeyBiweight(c)) step for step so that the two agree to rounding:
//   start: ordinary least squares;
//   scale: MAD about zero / 0.6745 of the current residuals, re-estimated every iteration;
//   weights: (1 - (r / (c * scale))^2)^2 for |r| <= c * scale, else 0;
//   converged: the change of the M-estimator's deviance between iterations <= tol, within
//   max_iter iterations (statsmodels' default rule, conv='dev'), taken relative to the
//   deviance by default: |d_k - d_k-1| <= tol * max(1, |d_k|). statsmodels' absolute rule
//   sits below the rounding of a sum of 60 000 pixels' terms and then converges by chance
//   (measured: a simulated fillet of 58 621 pixels took 31 iterations in statsmodels and did
//   not settle in 50 here); relative_tol = false gives statsmodels' rule exactly.
//   With relative_tol, a fit has also settled when an iteration moved the fitted curve by at
//   most settled_move of the residuals' scale anywhere over the points' thicknesses: IRLS on
//   some fillets creeps on geometrically (measured: a marbled fillet's curve moved by 1e-9
//   a step while its deviance still changed by 3e-8 relative after 50 iterations), and a
//   fit that moves by a ten-thousandth of its noise is as settled as a fit can be
//   (settled_move; 0: the deviance's rule alone).
#pragma once
#include <cstddef>

namespace rangex {

struct RobustFitOptions {
  double c = 5.0;  // the dissertation's tuning constant
  int max_iter = 50;
  double tol = 1e-8;
  bool relative_tol = true;
  double settled_move = 1e-4;  // of the residuals' scale; with relative_tol only
};

// The most that ln I = b[0] + b[1] T + b[2] T^2 moved from `prev` to `cur` over T in [lo, hi]
// (at the ends and the middle: within a few per cent of the maximum for a parabola).
double fit_move(const double prev[3], const double cur[3], double lo, double hi);

// Whether IRLS has settled after `iterations` (2 after the first reweighted fit): the
// deviance's rule, or (relative_tol) the curve `cur` within settled_move * scale of the one
// before (`prev`), or of the one two before (`before`: a 2-cycle, in which the weights and
// the MAD scale of quantised intensities flip between two sets and IRLS between two curves
// for good, 2 % of the scale apart on tests/test_robust_fit.cpp's 101 points; a creeping
// fit moves further in two iterations than in one, so only a cycle meets this).
// Over T in [lo, hi].
bool fit_settled(const RobustFitOptions& o, double dev, double dev_prev, const double before[3],
                 const double prev[3], const double cur[3], double lo, double hi, double scale,
                 int iterations);

struct RobustFit {
  double beta0 = 0, beta1 = 0;
  double beta2 = 0;    // the parabola's T^2 term (fit_tukey_poly with degree 2), else 0
  double scale = 0;    // final MAD scale of the residuals
  int iterations = 0;  // statsmodels' count: the OLS start is iteration 1
  bool converged = false;
  size_t n = 0;
  size_t inliers = 0;  // points with a non-zero final weight
};

// Throws Error for fewer than 3 points, non-finite values, x without spread, or a reweighting
// that leaves no two distinct x with weight.
RobustFit fit_tukey_line(const double* x, const double* y, size_t n,
                         const RobustFitOptions& o = {});

// The same with ln I = b0 + b1 T + b2 T^2 (degree 2): a polychromatic beam hardens in thick
// meat, so ln I bends away from the line (statsmodels' RLM on the design [1, T, T^2]).
// Throws as above, and for fewer than three distinct x (degree 2) or a degree not 1 or 2.
RobustFit fit_tukey_poly(const double* x, const double* y, size_t n, int degree,
                         const RobustFitOptions& o = {});

// Median as numpy computes it (mean of the two middle values for even n); may reorder `v`.
// Large inputs are bracketed by a sample and selected within the bracket. Floats give the
// median their doubles would, with half the memory to move.
double median_inplace(double* v, size_t n);
double median_inplace(float* v, size_t n);

// The Gaussian's 3/4 quantile: a median absolute deviation / kMadNormal is the standard
// deviation of Gaussian data.
inline constexpr double kMadNormal = 0.6744897501960817;

}  // namespace rangex
