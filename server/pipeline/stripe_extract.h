// Stage 1, stripe extraction (seed ch. 5): for every column of every frame in a batch, the
// sub-pixel row of the laser stripe, its peak intensity, window width and a valid flag.
//
// Per column: peak row p (first maximum), window = the connected run of pixels above
// T = threshold_rel * peak around p, weights g - T (continuous at the window edge, so the
// window's integer bounds do not bias the centroid), then:
//   centroid   C = sum y (g-T) / sum (g-T)                                   (eq. 15)
//   squared    the same with (g-T)^2
//   binary     midpoint of the interpolated half-maximum crossings
//   gaussian3  vertex of the parabola through ln g at p-1, p, p+1
//   parabola   vertex of the parabola through g at p-1, p, p+1
//   shifted    C + K1                                                        (eq. 18)
//   modified   C + K2off + K2 * a,  a = (phi - 1) / (phi + 1)                 (eq. 19-20)
// where phi = L / U is eq. 20's symmetry index: the weight below / above the sub-pixel
// (gaussian3) peak, split with fractional pixels. Eq. 19 applies K2 * phi through the
// origin, which shifts a symmetric stripe by K2 and, with the split at the integer peak,
// couples phi to the sub-pixel phase; a is zero for a symmetric stripe and the offset
// absorbs what is left of the skew (see docs/stripe-methods.md for the measurements).
#pragma once
#include <cstdint>
#include <vector>

#include "core/stripe_params.h"

namespace rangex {

struct StripeSlot {
  StripeParams params;
  ScatterConstants scatter;
};

struct StripeOutput {
  std::vector<float> row;       // sub-pixel row, NaN where invalid
  std::vector<float> peak;      // peak intensity (DN)
  std::vector<float> width;     // window width (px)
  std::vector<float> asym;      // a = (L - U) / (L + U)
  std::vector<float> centroid;  // plain centroid C (for fitting the scattering constants)
  std::vector<uint8_t> valid;
  void resize(size_t n);
};

// frames: `count` Mono8 frames of height x width, row-major, back to back; slot[i] selects
// frame i's settings in `slots`. Output holds count * width columns.
//
// The CPU path: the frame is streamed row by row once for the column maxima, then the
// window sums run over small bands of rows for groups of neighbouring columns so that the
// compiler vectorises them across columns. Frames are shared among `threads` threads.
void extract_stripes(const uint8_t* frames, int count, int width, int height, const int* slot,
                     const StripeSlot* slots, StripeOutput& out, int threads = 1);

// The same result computed one column at a time, exactly as a GPU kernel work-item does it;
// the reference the CPU path and the GPU kernels are tested against.
void extract_stripes_reference(const uint8_t* frames, int count, int width, int height,
                               const int* slot, const StripeSlot* slots, StripeOutput& out);

}  // namespace rangex
