// The probability of detecting a test piece as a function of its size, from hit/miss data:
// logit POD = a + b ln(size), the model of non-destructive testing's hit/miss analysis
// (MIL-HDBK-1823A). A sensitivity claim stands on the curve's lower confidence bound, not on
// the rate seen at one size: picking the smallest size whose 25 pieces were found at >= 95 %
// picks sizes that were lucky, and the claim then fails on other fillets.
//
// Fitted with Firth's penalised likelihood, which stays finite when every piece above some
// size was found and every one below missed (the usual case, where the plain maximum
// likelihood slope is infinite). The bound is the penalised profile likelihood's. The slope
// is held at b >= 0 in both: a larger piece is not harder to find.
#pragma once
#include <vector>

namespace rangex {

struct HitMiss {
  double size_mm = 0;
  int injected = 0, found = 0;
};

struct DetectionCurve {
  // logit POD = a + b ln(size_mm); b >= 0 (POD does not fall with size), and 0 where the
  // pieces had one size.
  double a = 0, b = 0;
  double penalised_loglik = 0;
  bool fitted = false;  // false: no pieces, or the fit did not settle
  double pod(double size_mm) const;
};

DetectionCurve fit_detection_curve(const std::vector<HitMiss>& data);

// The one-sided lower `confidence` bound of POD at `size_mm` (NaN when `curve` is not
// fitted): where twice the penalised profile log-likelihood falls by z^2 below its maximum.
double detection_lower_bound(const std::vector<HitMiss>& data, const DetectionCurve& curve,
                             double size_mm, double confidence);

}  // namespace rangex
