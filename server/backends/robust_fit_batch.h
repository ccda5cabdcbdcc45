// The robust fit ln I = b0 + b1 T of a batch of fillets with the per-pixel work on a backend:
// each IRLS iteration's residuals and weighted sums come from Backend::irls_sums (on a
// device, one work-group per fillet), the iteration logic stays here on the host: the MAD
// scale, the weighted line from the sums, the deviance and its convergence rule, exactly as
// fit_tukey_line (pipeline/robust_fit.h) runs them for one fillet.
#pragma once
#include <string>
#include <vector>

#include "backends/backend.h"
#include "pipeline/robust_fit.h"

namespace rangex {

struct BatchFit {
  RobustFit fit;
  std::string error;  // why the fit failed (fewer than 3 points, no spread in T, ...)
};

// `batch.models` is ignored: the fit sets its own. One result per fillet.
std::vector<BatchFit> fit_tukey_lines(Backend& backend, const FilletBatch& batch,
                                      const RobustFitOptions& o = {});

}  // namespace rangex
