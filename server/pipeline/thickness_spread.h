// A detection statistic's location and spread measured where it is computed: after the
// smoothing and matched kernels, robustly (median and MAD, so texture's and fat's heavy
// tails do not inflate it), and varying across the fillet with the meat's thickness
// (equal-count thickness bins, interpolated between their centres). Thick meat is rougher
// than thin meat; one spread per fillet made its tail look like bone.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rangex {

// The fillet's usable pixels ordered into equal-count thickness bins (once per fillet, for
// every statistic).
struct ThicknessBins {
  // Pixel indices per bin, the thinnest bin first; one bin's in image order, several bins' by
  // thickness.
  std::vector<std::vector<size_t>> members;
  std::vector<double> centre_mm;  // median thickness per bin
};

// At most max_bins bins of at least min_per_bin pixels (one bin for a small fillet).
ThicknessBins thickness_bins(const float* thickness, const uint8_t* use, size_t n, int max_bins = 8,
                             size_t min_per_bin = 3000);

struct SpreadProfile {
  std::vector<double> centre_mm, median, scale;  // per bin
  double median_at(double t) const;
  double scale_at(double t) const;
};

// Median and MAD / 0.6745 of v per bin, the scale never below `floor` (white noise's).
SpreadProfile spread_profile(const std::vector<float>& v, const ThicknessBins& bins, double floor);

// v <- (v - median(T)) / scale(T) on the usable pixels; returns the profile.
SpreadProfile unit_spread_by_thickness(std::vector<float>& v, const float* thickness,
                                       const uint8_t* use, const ThicknessBins& bins, double floor);

}  // namespace rangex
