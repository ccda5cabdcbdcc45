// A ray through the sandwich detector (core/sandwich_detector.h): each layer's reading for
// the materials the ray crosses, with the beam hardening the spectra give (no fit of any
// kind: each 1 keV bin is attenuated by NIST's coefficients), energy-integrating photon
// noise (normal approximation of Poisson, counts > 1000) and electronic noise.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "core/sandwich_detector.h"
#include "core/xray_materials.h"
#include "sim/rng.h"

namespace rangex::sim {

// Lengths along one ray, mm; bone is calcified to `calcification`.
struct RayMaterials {
  double lean = 0, fat = 0, cartilage = 0, tendon = 0, bone = 0, a150 = 0, aluminium = 0;
  double calcification = 1;
};

struct DualEnergyRenderParams {
  double open_beam_dn = 3600;   // each layer's open-beam reading (gains set so)
  double electronic_noise = 2;  // DN
};

class DualEnergyRenderer {
 public:
  explicit DualEnergyRenderer(const SandwichDetector& d, DualEnergyRenderParams p = {});
  // Each layer's mean reading (DN) and its variance (DN^2).
  void mean(const RayMaterials& r, double* low, double* high, double* var_low = nullptr,
            double* var_high = nullptr) const;
  // A reading drawn about the means and variances mean() gives (a ray's, or many rays'
  // through the same materials).
  static void draw(double m_lo, double m_hi, double v_lo, double v_hi, Rng& rng, uint16_t* low,
                   uint16_t* high);
  const LayerSpectra& spectra() const { return s_; }

 private:
  LayerSpectra s_;
  DualEnergyRenderParams p_;
  double low_photons_ = 0;            // SandwichDetector::low_photons
  double norm_lo_ = 0, norm_hi_ = 0;  // open-beam sum of photons x keV per layer
  std::vector<std::array<double, 7>>
      mu_;  // per bin, per mm: lean fat cartilage tendon bone a150 al
};

}  // namespace rangex::sim
