#include "pipeline/nelder_mead.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace rangex {

namespace {

struct Simplex {
  std::vector<std::vector<double>> x;
  std::vector<double> f;
};

// One run of the standard simplex (reflection 1, expansion 2, contraction 0.5, shrink 0.5).
void run(const std::function<double(const std::vector<double>&)>& fn, Simplex& s, double tol,
         int max_eval, int& evals) {
  const size_t n = s.x.size() - 1;
  std::vector<size_t> order(n + 1);
  auto eval = [&](const std::vector<double>& p) {
    ++evals;
    const double v = fn(p);
    return std::isfinite(v) ? v : HUGE_VAL;
  };
  while (evals < max_eval) {
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return s.f[a] < s.f[b]; });
    const size_t best = order.front(), worst = order.back(), second = order[n - 1];
    if (std::abs(s.f[worst] - s.f[best]) <= tol * std::max(1.0, std::abs(s.f[best]))) return;
    std::vector<double> c(n, 0.0);
    for (size_t k : order)
      if (k != worst)
        for (size_t j = 0; j < n; ++j) c[j] += s.x[k][j] / double(n);
    auto along = [&](double t) {
      std::vector<double> p(n);
      for (size_t j = 0; j < n; ++j) p[j] = c[j] + t * (s.x[worst][j] - c[j]);
      return p;
    };
    const auto xr = along(-1);
    const double fr = eval(xr);
    if (fr < s.f[best]) {
      const auto xe = along(-2);
      const double fe = eval(xe);
      if (fe < fr)
        s.x[worst] = xe, s.f[worst] = fe;
      else
        s.x[worst] = xr, s.f[worst] = fr;
    } else if (fr < s.f[second]) {
      s.x[worst] = xr, s.f[worst] = fr;
    } else {
      const bool outside = fr < s.f[worst];
      const auto xc = along(outside ? -0.5 : 0.5);
      const double fc = eval(xc);
      if (fc < (outside ? fr : s.f[worst])) {
        s.x[worst] = xc, s.f[worst] = fc;
      } else {
        for (size_t k = 0; k <= n; ++k) {
          if (k == best) continue;
          for (size_t j = 0; j < n; ++j)
            s.x[k][j] = s.x[best][j] + 0.5 * (s.x[k][j] - s.x[best][j]);
          s.f[k] = eval(s.x[k]);
        }
      }
    }
  }
}

}  // namespace

NelderMeadResult nelder_mead(const std::function<double(const std::vector<double>&)>& f,
                             std::vector<double> x0, const std::vector<double>& step, double tol,
                             int max_evaluations) {
  NelderMeadResult r;
  const size_t n = x0.size();
  double last = HUGE_VAL;
  // Restarts from the best point with fresh steps: a simplex can collapse onto a subspace.
  for (int restart = 0; restart < 6 && r.evaluations < max_evaluations; ++restart) {
    Simplex s;
    s.x.push_back(x0);
    for (size_t j = 0; j < n; ++j) {
      auto p = x0;
      p[j] += step[j] * (restart == 0 ? 1.0 : 0.3);
      s.x.push_back(p);
    }
    for (const auto& p : s.x) {
      const double v = f(p);
      s.f.push_back(std::isfinite(v) ? v : HUGE_VAL);
      ++r.evaluations;
    }
    run(f, s, tol, max_evaluations, r.evaluations);
    const size_t best = size_t(std::min_element(s.f.begin(), s.f.end()) - s.f.begin());
    x0 = s.x[best];
    r.value = s.f[best];
    if (std::abs(last - r.value) <= tol * std::max(1.0, std::abs(r.value))) {
      r.converged = true;
      break;
    }
    last = r.value;
  }
  r.x = x0;
  return r;
}

}  // namespace rangex
