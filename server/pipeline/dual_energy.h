// The dual-energy decomposition with the laser's thickness, per pixel, over a flat batch: the
// CPU reference of the kernels (one pixel a work-item). A pixel's two log attenuations
// x = ln(open_low / low), y = ln(open_high / high) give the lengths A of A-150 and B of
// aluminium that attenuate alike: the lane's calibration has each log attenuation as a polynomial
// in (A, B) (DEXA's basis decomposition, fitted forward), inverted here by Newton's method; with
// the laser's path length T through the meat, the three equations
//   A = a_lean t_lean + a_fat t_fat + a_bone t_bone
//   B = b_lean t_lean + b_fat t_fat + b_bone t_bone
//   T = t_lean + t_fat + t_bone
// give the lengths of lean, fat and bone (cortical-bone equivalent) along the ray. Their
// uncertainty comes from the photon counts (each layer's var(ln I) = (gain I + var_e) / I^2), the
// calibration's residuals and the thickness's variance, carried through the polynomials'
// inverse Jacobian and the 3 x 3 inverse (docs/dual-energy.md). Pixels not usable, or dark,
// give NaN.
#pragma once
#include <cstdint>

#include "shared/dual_energy.h"

namespace rangex {

using DualEnergyParams = kernel::DualEnergyK;

struct DualEnergyBatch {
  const uint16_t* low = nullptr;    // DN of the low-energy layer, per pixel
  const uint16_t* high = nullptr;   // DN of the high-energy layer
  const float* open_low = nullptr;  // each pixel's open-beam reading, per layer
  const float* open_high = nullptr;
  const float* thickness = nullptr;  // the laser's path length through the meat, mm
  const uint8_t* use = nullptr;      // 1: a fillet pixel (null: every pixel)
  int pixels = 0;
};

// Step 4's inputs over a batch (the backends' bone stage).
struct DualEnergyBoneBatch {
  const float* basis = nullptr;      // step 1's: 5 a pixel
  const float* thickness = nullptr;  // mm
  const float* phi = nullptr;        // the fat's share of the soft tissue, and its variance
  const float* phi_var = nullptr;
  int pixels = 0;
  double density_var = 0;  // see dual_energy_bone
};

// Throw Error naming what is wrong: an input missing, a negative count, parameters that are
// no calibration (the linear terms cannot be inverted, or not finite).
void check_dual_energy_batch(const DualEnergyBatch& b, const DualEnergyParams& k);
void check_dual_energy_batch(const DualEnergyBoneBatch& b, const DualEnergyParams& k);

// Per pixel: lengths[3 p + m] and sigma[3 p + m], m = 0 lean, 1 fat, 2 bone (mm): the two
// steps below in one.
void dual_energy_decompose(const DualEnergyBatch& b, const DualEnergyParams& k, float* lengths,
                           float* sigma);

// Step 1, per pixel: basis[5 p ..] = A, B (mm), var A, cov AB, var B (mm^2; the counts
// and the calibration's own error); NaN for pixels not usable or outside the calibration.
void dual_energy_basis(const DualEnergyBatch& b, const DualEnergyParams& k, float* basis);

// Step 2, per pixel: the three lengths with the laser's thickness, and their sigmas. Unbiased
// but noisy: lean and fat attenuate almost alike at both energies, so their split (and the
// bone that depends on it) carries the counts' noise many times over.
void dual_energy_lengths(const float* basis, const float* thickness, int pixels,
                         const DualEnergyParams& k, float* lengths, float* sigma);

// Bone given the fat's share phi of the soft tissue (fat / (lean + fat), smooth over the
// fillet: pipeline/fat_fraction.h): per pixel the bone length t that best explains (A, B)
// as soft tissue of that mix over T - t and bone over t, weighted by the pair's covariance
// the thickness's variance and phi's (generalised least squares, one unknown), and its sigma.
// density_var: the soft tissue's density varies pixel to pixel by this relative variance
// (cartilage, tendon, texture); it enters like the thickness's variance, along s.
void dual_energy_bone(const float* basis, const float* thickness, const float* phi,
                      const float* phi_var, int pixels, const DualEnergyParams& k, float* bone,
                      float* bone_sigma, double density_var = 0);

// The polynomial's terms at (u, v), its value and its gradient.
void dual_energy_terms(double u, double v, double* t);
double dual_energy_poly(const double* c, double u, double v);
void dual_energy_gradient(const double* c, double u, double v, double* du, double* dv);
// The basis lengths (A, B) in mm whose log attenuations are (x, y); false when Newton's
// method does not settle (a reading outside what the calibration covers).
bool dual_energy_invert(const DualEnergyParams& k, double x, double y, double* a, double* b,
                        double jinv[4]);

}  // namespace rangex
