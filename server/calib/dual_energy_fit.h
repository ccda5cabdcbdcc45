// The dual-energy calibration of a lane from a step-wedge scan (core/dual_energy_wedge.h):
// - DEXA's basis decomposition, fitted forward: each layer's log attenuation as a polynomial
// (degree 5) in
//   the wedge's two thicknesses, weighted least squares over the steps; the error of the
//   thicknesses taken back from each step's readings (pipeline/dual_energy.h inverts it);
// - each layer's noise (var = gain x DN + electronic) from the steps' variances;
// - each material (lean, fat, bone) as lengths of the two basis materials per mm: slabs of
//   it over its usual range, their readings computed from NIST's coefficients through the
//   detector's nominal spectra (core/sandwich_detector.h), taken back through the fitted
//   calibration, and the lengths' slope through the origin.
// Together with the laser's thickness they make the decomposition's parameters
// (pipeline/dual_energy.h).
#pragma once
#include <array>
#include <string>
#include <vector>

#include "core/dual_energy_wedge.h"
#include "core/sandwich_detector.h"
#include "core/xray_materials.h"
#include "pipeline/dual_energy.h"

namespace rangex {

struct DualEnergyFit {
  DualEnergyParams params{};
  struct Step {
    double a150_mm, al_mm, a_fit, b_fit;
  };
  std::vector<Step> steps;                  // the fit at each step
  double a_rms = 0, b_rms = 0;              // mm
  double a_worst_rel = 0, b_worst_rel = 0;  // largest |error| / thickness, steps >= 1 mm
};

// Throws Error naming what is wrong: too few steps, a step darker than the noise, an open
// beam missing.
DualEnergyFit fit_dual_energy(const WedgeScan& scan, const SandwichDetector& nominal,
                              double laser_sigma_mm);

// The thicknesses taken back from each step of a scan (NaN where it cannot be inverted).
std::vector<DualEnergyFit::Step> evaluate_wedge(const DualEnergyParams& p, const WedgeScan& scan);

// Material m per mm as (A-150 mm, Al mm) through the calibration p (see above).
std::array<double, 2> basis_lengths(Material m, const LayerSpectra& s, const DualEnergyParams& p);

// A plain-text report: the fit's residuals, worst step, gains, basis lengths.
std::string dual_energy_report(const DualEnergyFit& f);

}  // namespace rangex
