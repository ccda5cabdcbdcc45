// Gaussian smoothing restricted to a mask (normalised convolution): pixels outside the mask
// neither contribute nor receive values, so a fillet's edge does not pull in the belt.
#pragma once
#include <cstdint>
#include <vector>

namespace rangex {

// out = (G * (v m)) / (G * m) inside the mask, NaN outside; sigma in pixels (> 0).
void masked_gaussian(const float* v, const uint8_t* mask, int rows, int cols, double sigma,
                     std::vector<float>& out);

// sqrt(sum k^2) of the normalised 2-D kernel: the factor by which smoothing shrinks the
// standard deviation of white noise (away from the mask's edge).
double gaussian_noise_gain(double sigma);

// An elongated Gaussian, for thin features (needles): sigma_along pixels along one of four
// directions (0: the rows, 1: the columns, 2: the diagonal x = y, 3: x = -y), then
// sigma_across pixels across it (for the diagonals, along the rows), masked as above.
// Returns the kernel's white-noise gain (as gaussian_noise_gain).
double masked_line_gaussian(const float* v, const uint8_t* mask, int rows, int cols,
                            double sigma_along, double sigma_across, int direction,
                            std::vector<float>& out);

// How far from its pixel any smoothing above reaches, in pixels: the along kernel's radius
// plus, for an elongated one (sigma_across > 0), the across kernel's.
int smooth_reach_px(double sigma_along, double sigma_across = 0);

// The same smoothings evaluated at one pixel (r, c) only (direction -1: the round
// masked_gaussian of sigma_along), for a few pixels where whole images would cost more.
double masked_smooth_at(const float* v, const uint8_t* mask, int rows, int cols, double sigma_along,
                        double sigma_across, int direction, int r, int c);

}  // namespace rangex
