// The fat's share of a fillet's soft tissue, phi = fat / (lean + fat), as a smooth map: the
// per-pixel lengths of the full decomposition (pipeline/dual_energy.h, step 2) are unbiased
// but noisy, so their sums over a neighbourhood (a masked Gaussian of sigma_px) give phi.
// Bone does not bias it: the full decomposition separates bone as it separates fat. Fat
// varies over centimetres (marbling streaks are averaged); a fragment is millimetres.
#pragma once
#include <cstdint>
#include <vector>

namespace rangex {

// lengths, sigma: 3 per pixel (lean, fat, bone), rows x cols; phi clamped to 0..1 and its
// variance (the fat lengths' noise through the smoothing), measured over `mask` and given on
// `fill` (null: the mask; a pixel of fill off the mask takes its neighbourhood's), NaN
// elsewhere.
void fat_fraction_map(const float* lengths, const float* sigma, const uint8_t* mask, int rows,
                      int cols, double sigma_px, std::vector<float>& phi,
                      std::vector<float>& phi_var, const uint8_t* fill = nullptr);

}  // namespace rangex
