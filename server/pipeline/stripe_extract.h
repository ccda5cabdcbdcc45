// Stage 1, stripe extraction (Laser Range Imaging ch. 5): for every column of every frame in a
// batch, the sub-pixel row of the laser stripe, its peak intensity, window width and a valid flag.
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

#include "core/aligned_vector.h"
#include "core/stripe_params.h"

namespace rangex {

struct StripeSlot {
  StripeParams params;
  ScatterConstants scatter;
};

struct StripeOutput {
  // Cache-line aligned, so that a large batch's results can be streamed past the cache.
  AlignedVector<float> row;       // sub-pixel row, NaN where invalid
  AlignedVector<float> peak;      // peak intensity (DN)
  AlignedVector<float> width;     // window width (px)
  AlignedVector<float> asym;      // a = (L - U) / (L + U)
  AlignedVector<float> centroid;  // plain centroid C (for fitting the scattering constants)
  AlignedVector<uint8_t> valid;
  void resize(size_t n);
};

// frames: `count` Mono8 frames of height x width, row-major, back to back; slot[i] selects
// frame i's settings in `slots`. Output holds count * width columns.
//
// The CPU path: the frame is streamed row by row once for the column maxima, then the
// window walks and sums run over small bands of rows for blocks of neighbouring columns,
// one vector lane per column (AVX-512 blocks of 64 where the CPU has it, else groups of 16
// that the compiler vectorises), while the next frame is prefetched. Frames are shared
// among `threads` threads. `vector_blocks` false takes the portable groups whatever the CPU
// has (the CPU backend's `cpu-portable` variant, tested like every backend).
void extract_stripes(const uint8_t* frames, int count, int width, int height, const int* slot,
                     const StripeSlot* slots, StripeOutput& out, int threads = 1,
                     bool vector_blocks = true);

// Which vector blocks this build uses: "AVX-512 blocks of 64 columns" or the portable groups.
const char* stripe_vector_path();

// The same result computed one column at a time, exactly as a GPU kernel work-item does it;
// the reference the CPU path and the GPU kernels are tested against.
void extract_stripes_reference(const uint8_t* frames, int count, int width, int height,
                               const int* slot, const StripeSlot* slots, StripeOutput& out);

}  // namespace rangex
