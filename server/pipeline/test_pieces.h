// Synthetic test pieces injected into a fillet's own X-ray counts by Beer-Lambert, the way a
// plant proves an X-ray machine's sensitivity with calibrated test pieces: a calcified
// sphere or needle at a chosen place and depth multiplies the counts under it by
// exp(-excess_mu * chord), integrated over each detector pixel, magnified by the fan beam at
// its height and blurred across the detector by the lane's measured line spread and focal
// spot. The meat, its texture and its noise are the fillet's own.
#pragma once
#include "pipeline/fillet_image.h"

namespace rangex {

struct TestPiece {
  enum Shape { kSphere, kNeedle } shape = kSphere;
  double size_mm = 2;    // sphere diameter, needle length
  int row = 0, col = 0;  // centre, fillet pixel
  double height_mm = 0;  // centre above the belt
  double angle_rad = 0;  // needle direction in the belt's plane (0: across the belt)
};

struct TestPieceMaterial {
  // Excess attenuation over the meat per mm of path: `excess_per_mm` if > 0, else
  // `excess_ratio` times the meat's own attenuation (bone-equivalent: calcified bone
  // attenuates about 3x soft tissue at 50-70 kV, hence the default 2).
  double excess_ratio = 2.0;
  double excess_per_mm = 0;
  double needle_diameter_mm = 0.6;
  double excess(double meat_mu_per_mm) const {
    return excess_per_mm > 0 ? excess_per_mm : excess_ratio * meat_mu_per_mm;
  }
};

// Multiplies img.xray under the piece (meat_mu_per_mm: the meat's attenuation there, e.g.
// the fillet's fitted slope).
// high_excess_per_mm: a dual-energy fillet's high line attenuated too, by this excess (the
// piece's own in that layer; 0: the low line only).
void inject_test_piece(FilletImage& img, const TestPiece& piece, double meat_mu_per_mm,
                       const TestPieceMaterial& material, double high_excess_per_mm = 0);

}  // namespace rangex
