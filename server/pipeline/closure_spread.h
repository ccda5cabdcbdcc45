// A closed gap's error is one error along the gap (wall_gaps.h): wherever the step stood, it
// stood there for the whole gap and for the gap's neighbours along the wall. A kernel sums
// such an error coherently, where it averages independent noise down, so the pixel's own
// variance (closure_variance) understates it under every kernel that reaches the gap. Its
// share of a statistic under kernel h is at most sum |h| e, e the closure's spread in z's
// units per pixel; the statistic, already at unit spread, is divided by sqrt(1 + (that /
// scale)^2) (its scale: the spread it was brought to unit with). A closure alone then stays
// under sqrt(3) (the uniform error's largest over its spread), whatever the step.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pipeline/thickness_spread.h"

namespace rangex {

struct ClosureReach {
  std::vector<float> e;        // per pixel, z's units; 0 where nothing was closed
  std::vector<size_t> near;    // the usable pixels within `reach` of a closed one
  std::vector<size_t> closed;  // the pixels with e > 0
  bool empty() const { return near.empty(); }
};

// e: per pixel (empty: no closure). reach: the largest kernel's half-width in pixels.
ClosureReach closure_reach(std::vector<float> e, const uint8_t* use, int rows, int cols, int reach);

// v <- v / sqrt(1 + (sums[k] / scale(T_i))^2) at each pixel i = cr.near[k] near a closure,
// where sums[k] is the kernel's sum of |h| e there and s the profile v was brought to unit
// spread with.
void discount_closures(std::vector<float>& v, const ClosureReach& cr, const float* thickness,
                       const SpreadProfile& s, const std::vector<double>& sums);

// A kernel's sum of `taps` times e at each of cr.near's pixels (in its order), the window
// (2 radius + 1)^2 centred there as apply_kernel_at reads it: each closed pixel's e is
// scattered over its window instead, since the closed pixels (a rim, a lost line) are a
// few to the many near them. `acc`: a scratch of rows x cols zeros, left zeroed.
std::vector<double> closure_kernel_sums(const ClosureReach& cr, int rows, int cols,
                                        const std::vector<double>& taps, int radius,
                                        std::vector<double>& acc);

}  // namespace rangex
