// fit: the robust line ln I = b0 + b1 T (or with --degree 2 the parabola + b2 T^2) of a
// two-column CSV, as the inspection fits it.
#include <cstdio>

#include "args.h"
#include "commands.h"
#include "core/error.h"
#include "offline/csv_points.h"
#include "pipeline/robust_fit.h"

namespace rangex::cli {

int cmd_fit(int argc, char** argv) {
  const Args a(argc, argv, 2, {"json", "absolute-tol"}, {"c", "max-iter", "tol", "degree"});
  a.expect_positionals(1, "fit FILE.csv [--c C] [--degree 1|2] [--json]");
  const CsvColumns d = read_two_column_csv(a.positional(0, "CSV file"));
  RobustFitOptions o;
  o.c = std::stod(a.get("c", "5"));
  o.max_iter = int(a.integer("max-iter", 50));
  o.tol = std::stod(a.get("tol", "1e-8"));
  o.relative_tol = !a.flag("absolute-tol");
  const int degree = int(a.integer("degree", 1));
  if (degree != 1 && degree != 2) fail("--degree must be 1 (a line) or 2 (a parabola)");
  const RobustFit f = fit_tukey_poly(d.x.data(), d.y.data(), d.x.size(), degree, o);
  if (a.flag("json")) {
    std::printf(
        "{\"beta0\": %.12g, \"beta1\": %.12g, \"beta2\": %.12g, \"scale\": %.12g, "
        "\"iterations\": %d, \"converged\": %s, \"n\": %zu, \"inliers\": %zu, \"c\": %g}\n",
        f.beta0, f.beta1, f.beta2, f.scale, f.iterations, f.converged ? "true" : "false", f.n,
        f.inliers, o.c);
  } else {
    std::printf("%s = b0 + b1 * %s%s  (Tukey biweight, c = %g, %zu points)\n", d.y_name.c_str(),
                d.x_name.c_str(), degree == 2 ? (" + b2 * " + d.x_name + "^2").c_str() : "", o.c,
                f.n);
    std::printf(
        "b0          %.10g\nb1          %.10g\nscale       %.6g\niterations  %d\n"
        "converged   %s\ninliers     %zu of %zu\n",
        f.beta0, f.beta1, f.scale, f.iterations, f.converged ? "yes" : "no", f.inliers, f.n);
    if (degree == 2) std::printf("b2          %.10g\n", f.beta2);
  }
  return f.converged ? 0 : 4;
}

}  // namespace rangex::cli
