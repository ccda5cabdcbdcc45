// Steep walls hide their foot from the cameras: the fused profile has no height there, and
// the detector pixels whose rays cross that stretch get no thickness, a rim one to a few
// pixels wide along the wall. Such a short gap between a pixel on the meat and a pixel off
// it is closed as a vertical wall in the gap's middle (the side it faces keeps its height),
// so the rim is inspected rather than failing the fillet. A row with no thickness at all (a
// lost camera frame) is closed along the columns the same way. Longer gaps stay unmeasured
// (and count toward the fail-safe).
//
// Nothing says where within the gap the wall stood (a fold's oblique step may rise anywhere
// in it) or, on a lost row, where a step between the rows either side stood: a closed
// pixel's thickness lies somewhere between the gap's ends. img.closure_step_mm says how far
// they differ, for the noise model to carry.
#pragma once
#include <functional>
#include <vector>

#include "pipeline/fillet_image.h"

namespace rangex {

// Closes gaps of at most max_gap_px pixels along rows, then along columns; a closed pixel
// above floor_mm joins the mask. Returns how many pixels were closed.
int close_wall_gaps(FilletImage& img, int max_gap_px, double floor_mm);

// The fillet's own rim is a wall of the same kind: its outline crosses the outermost pixel
// of a row (or of a column) somewhere within it, and nothing measured says where. That
// pixel's thickness lies between the belt's (0) and its inner neighbour's h; measured a, its
// error is uniform over [-a, h - a] at worst, of mean square (a^3 + (h - a)^3) / (3 h): the
// step whose step^2 / 3 is that. Per pixel, 0 off the outline. A tapering rim (a and h
// small) carries little; a cliff (a fold's flap standing at the outline) carries its height.
std::vector<float> rim_steps(const FilletImage& img);

// The variance of ln P that the closures leave, per pixel (empty when there are none): a
// closed pixel's thickness lies anywhere between its gap's ends, the closure took one of
// them, so (mu(T) * step)^2 / 3 with mu(T) = -d ln P / dT, the meat's attenuation per mm
// at the pixel's thickness. With `rim`, the outline's pixels carry rim_steps the same way.
// Spread to the rows either side, where the registration's fraction of a line carries it.
std::vector<float> closure_variance(const FilletImage& img, const std::function<double(double)>& mu,
                                    bool rim = false);

}  // namespace rangex
