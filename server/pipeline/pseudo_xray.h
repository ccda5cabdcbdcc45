// The CPU reference of the pseudo-X-ray stages over a flat batch of fillets, the shape of the
// kernels (kernels/pseudo_xray.cl, shaders/pseudo_xray.comp, shaders/irls_sums.comp):
//   pseudo_xray_map: per usable pixel, ln P = b0 + b1 T, P = exp(ln P), the residual
//     ln I - ln P, and the noise-normalised z = residual / sigma_ln(P) (Laser Range Imaging eq. 51,
//     64);
//   irls_sums: per usable pixel the residual r = ln I - (b0 + b1 T) and its Tukey weight,
//     and per fillet the weighted sums one IRLS iteration of the robust fit needs
//     (the iteration logic, the MAD scale and convergence, stays on the host).
// Pixels not usable get NaN. Arithmetic as in inspection.cpp, so that the two agree.
#pragma once
#include <cstdint>

#include "shared/fillet_tables.h"

namespace rangex {

using FilletModel = kernel::FilletModelK;

struct FilletBatch {
  const float* thickness = nullptr;  // mm, per pixel
  const uint16_t* xray = nullptr;    // DN, per pixel
  const uint8_t* use = nullptr;      // 1: a usable fillet pixel
  const int32_t* offsets = nullptr;  // fillets + 1 entries, offsets[0] = 0
  int fillets = 0;
  const FilletModel* models = nullptr;
  int pixels() const { return fillets ? offsets[fillets] : 0; }
};

void pseudo_xray_map(const FilletBatch& b, float* ln_p, float* p, float* residual, float* z);

// r: per pixel (double); sums: IRLS_SUMS per fillet.
void irls_sums(const FilletBatch& b, double* r, double* sums);

// Throws Error for offsets that do not rise from 0, a model that is not finite.
void check_fillet_batch(const FilletBatch& b);

}  // namespace rangex
