// The thickness as the X-ray detector would see it: the laser measures a sharp
// slice of the belt at whole lines, the detector a blurred one, a fraction of a line
// further and along a plane turned against the laser's. Before the pseudo-X-ray is fitted,
// a fillet's registered thickness is
//   1. resampled along the belt by delay(x, z) - delay_lines lines at each pixel (z: half
//      the meat's thickness there, where its ray crosses it; the X-ray line integrates
//      the belt's travel over one line, so neighbouring rows are interpolated), and
//   2. blurred across the detector by its line-spread function and the focal spot's image
//      (which grows with height),
// both over the transmission: the detector averages intensities, exp(-mu T), not
// thicknesses, so T_eff = -ln(sum_k w_k exp(-mu T_k)) / mu, with mu the meat's attenuation
// (the fillet's own fit: -b1).
// Without a measured registration and blur the image is left as it is.
#pragma once
#include "pipeline/fillet_image.h"

namespace rangex {

// mu_per_mm > 0. Pixels without thickness stay NaN and take no part in their neighbours'
// blur.
void match_detector(FilletImage& img, double mu_per_mm);

}  // namespace rangex
