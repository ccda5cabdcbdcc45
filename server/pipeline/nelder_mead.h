// Derivative-free minimisation (Nelder-Mead simplex, with restarts from the best point), for
// small likelihoods whose gradients are not worth writing (the GEV fits of product learning).
#pragma once
#include <functional>
#include <vector>

namespace rangex {

struct NelderMeadResult {
  std::vector<double> x;
  double value = 0;
  int evaluations = 0;
  bool converged = false;
};

// Minimises f from x0 with initial steps `step` (one per coordinate); converged when the
// simplex's values span less than tol (relative to max(1, |f|)) after a restart.
NelderMeadResult nelder_mead(const std::function<double(const std::vector<double>&)>& f,
                             std::vector<double> x0, const std::vector<double>& step,
                             double tol = 1e-9, int max_evaluations = 20000);

}  // namespace rangex
