// Steep walls hide their foot from the cameras: the fused profile has no height there, and
// the detector pixels whose rays cross that stretch get no thickness, a rim one to a few
// pixels wide along the wall. Such a short gap between a pixel on the meat and a pixel off
// it is closed as a vertical wall in the gap's middle (the side it faces keeps its height),
// so the rim is inspected rather than failing the fillet; where the wall stood within the
// gap is uncertain by half the gap, which the noise model's gradient term carries.
// Longer gaps stay unmeasured (and count toward the fail-safe).
#pragma once
#include "pipeline/fillet_image.h"

namespace rangex {

// Closes gaps of at most max_gap_px pixels along rows, then along columns; a closed pixel
// above floor_mm joins the mask. Returns how many pixels were closed.
int close_wall_gaps(FilletImage& img, int max_gap_px, double floor_mm);

}  // namespace rangex
