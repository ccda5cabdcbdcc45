#include "sim/dual_energy_renderer.h"

#include <algorithm>
#include <cmath>

namespace rangex::sim {

DualEnergyRenderer::DualEnergyRenderer(const SandwichDetector& d, DualEnergyRenderParams p)
    : s_(layer_spectra(d)), p_(p), low_photons_(d.low_photons) {
  for (size_t k = 0; k < s_.kev.size(); ++k) {
    const double e = s_.kev[k];
    norm_lo_ += s_.low[k] * e;
    norm_hi_ += s_.high[k] * e;
    mu_.push_back({attenuation_per_mm(Material::kLean, e), attenuation_per_mm(Material::kFat, e),
                   attenuation_per_mm(Material::kCartilage, e),
                   attenuation_per_mm(Material::kTendon, e), attenuation_per_mm(Material::kBone, e),
                   attenuation_per_mm(Material::kA150, e),
                   attenuation_per_mm(Material::kAluminium, e)});
  }
}

void DualEnergyRenderer::mean(const RayMaterials& r, double* low, double* high, double* var_low,
                              double* var_high) const {
  double sig_lo = 0, sig_hi = 0, sq_lo = 0, sq_hi = 0;
  const double c = std::clamp(r.calcification, 0.0, 1.0);
  for (size_t k = 0; k < s_.kev.size(); ++k) {
    const auto& m = mu_[k];
    const double att = m[0] * r.lean + m[1] * r.fat + m[2] * r.cartilage + m[3] * r.tendon +
                       (c * m[4] + (1 - c) * m[2]) * r.bone + m[5] * r.a150 + m[6] * r.aluminium;
    const double t = std::exp(-att), e = s_.kev[k];
    sig_lo += s_.low[k] * t * e, sq_lo += s_.low[k] * t * e * e;
    sig_hi += s_.high[k] * t * e, sq_hi += s_.high[k] * t * e * e;
  }
  // Photons absorbed in the open beam: N (low layer), N x high_photons_per_low (high).
  const double n_lo = low_photons_, n_hi = low_photons_ * s_.high_photons_per_low;
  *low = p_.open_beam_dn * sig_lo / norm_lo_;
  *high = p_.open_beam_dn * sig_hi / norm_hi_;
  const double en2 = p_.electronic_noise * p_.electronic_noise;
  // var(sum of n E) = sum of n E^2 for Poisson counts, in DN.
  if (var_low)
    *var_low = p_.open_beam_dn * p_.open_beam_dn * sq_lo / (n_lo * norm_lo_ * norm_lo_) + en2;
  if (var_high)
    *var_high = p_.open_beam_dn * p_.open_beam_dn * sq_hi / (n_hi * norm_hi_ * norm_hi_) + en2;
}

void DualEnergyRenderer::draw(double m_lo, double m_hi, double v_lo, double v_hi, Rng& rng,
                              uint16_t* low, uint16_t* high) {
  auto dn = [](double v) { return uint16_t(std::clamp(std::lround(v), 0L, 65535L)); };
  *low = dn(m_lo + std::sqrt(v_lo) * rng.normal());
  *high = dn(m_hi + std::sqrt(v_hi) * rng.normal());
}

}  // namespace rangex::sim
