// Inputs of the dual-energy stages made from the simulator, shared by the backend suite and
// `rangexctl bench`: the lane's calibration fitted from a simulated wedge scan, and rays
// through known materials drawn on the same sandwich detector with the laser's noise on
// their thickness.
#pragma once
#include <cstdint>
#include <vector>

#include "pipeline/dual_energy.h"
#include "sim/dual_energy_renderer.h"

namespace rangex {

// The simulator's nominal sandwich detector and its calibration from a wedge scan of
// `pixels_per_step` pixels a step (seed 1), the laser's sigma 0.05 mm.
struct DualEnergyCalibrated {
  sim::DualEnergyRenderer detector;
  DualEnergyParams params{};
  double open_low = 0, open_high = 0;  // the scan's open beam, DN
};
DualEnergyCalibrated calibrate_dual_energy(int pixels_per_step);

// Rays for the decomposition: both layers' readings, their open beams, the laser's thickness
// (the rays' total length plus its noise) and use flags.
struct DualEnergyRays {
  std::vector<uint16_t> low, high;
  std::vector<float> open_low, open_high, thickness;
  std::vector<uint8_t> use;
  int pixels() const { return int(low.size()); }
  DualEnergyBatch batch() const;
  // `n` rays through `r`, drawn with `seed`.
  void add(const DualEnergyCalibrated& c, const sim::RayMaterials& r, int n, double laser_mm,
           uint64_t seed);
};

// A mixed batch of `pixels` rays for the stage cases: lean 0-45 mm, fat 0-12 mm, bone 0-4 mm
// at calcification 0.3-1, cartilage, each ray its own; among them pixels not used, dark
// (0 DN), saturated and thinner than nothing (outside the calibration): the reference's NaNs.
DualEnergyRays mixed_dual_energy_rays(const DualEnergyCalibrated& c, int pixels, uint64_t seed);

}  // namespace rangex
