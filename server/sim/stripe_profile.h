// One column of a laser stripe as the camera sees it (seed eq. 13-14): a pixel-integrated
// Gaussian core plus a one-sided exponential scattering tail (convolved with the core),
// with multiplicative speckle. Adds onto the pixels already in the column.
#pragma once
#include <cstdint>

#include "sim/rng.h"

namespace rangex::sim {

struct StripeShape {
  double center;      // true row of the stripe centre
  double amplitude;   // DN at the core's peak
  double sigma;       // core standard deviation, px
  double tail;        // tail energy / core energy
  double tail_px;     // tail decay length, px
  int tail_sign;      // +1: tail toward larger rows
  double speckle;     // per-pixel multiplicative noise (std)
};

// column points at row 0 of the column; stride is the frame width.
void add_stripe(uint8_t* column, int height, int stride, const StripeShape& s, Rng& rng);

}  // namespace rangex::sim
