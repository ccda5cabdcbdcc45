#include "core/sandwich_detector.h"

#include <cmath>

#include "core/error.h"
#include "core/xray_materials.h"

namespace rangex {

LayerSpectra layer_spectra(const SandwichDetector& d) {
  if (!(d.kvp >= 30 && d.kvp <= 150)) fail("dual energy: kvp ", d.kvp, " must be 30..150 kV");
  if (!(d.front_csi_mm > 0 && d.back_csi_mm > 0 && d.filter_cu_mm >= 0 && d.tube_filter_al_mm >= 0))
    fail("dual energy: the detector's layers must be > 0 mm and its filters >= 0 mm");
  LayerSpectra s;
  double n_lo = 0, n_hi = 0, e_lo = 0, e_hi = 0;
  for (double e = 15.5; e < d.kvp; e += 1) {
    const double tube =
        (d.kvp - e) / e *
        std::exp(-attenuation_per_mm(Material::kAluminium, e) * d.tube_filter_al_mm);
    const double mu_csi = attenuation_per_mm(Material::kCsI, e);
    const double front = 1 - std::exp(-mu_csi * d.front_csi_mm);
    const double through = std::exp(-mu_csi * d.front_csi_mm) *
                           std::exp(-attenuation_per_mm(Material::kCopper, e) * d.filter_cu_mm);
    const double back = through * (1 - std::exp(-mu_csi * d.back_csi_mm));
    s.kev.push_back(e);
    s.low.push_back(tube * front);
    s.high.push_back(tube * back);
    n_lo += tube * front, n_hi += tube * back;
    e_lo += tube * front * e, e_hi += tube * back * e;
  }
  double m_lo = 0, m_hi = 0;
  for (size_t k = 0; k < s.kev.size(); ++k) {
    m_lo += s.low[k] * s.kev[k] * s.kev[k] / e_lo;
    m_hi += s.high[k] * s.kev[k] * s.kev[k] / e_hi;
    s.low[k] /= n_lo;
    s.high[k] /= n_hi;
  }
  s.high_photons_per_low = n_hi / n_lo;
  s.low_mean_kev = m_lo;
  s.high_mean_kev = m_hi;
  return s;
}

void layer_log_attenuations(const LayerSpectra& s, const std::function<double(double)>& att,
                            double* low, double* high) {
  double open_lo = 0, open_hi = 0, lo = 0, hi = 0;
  for (size_t k = 0; k < s.kev.size(); ++k) {
    const double e = s.kev[k], t = std::exp(-att(e));
    open_lo += s.low[k] * e, open_hi += s.high[k] * e;
    lo += s.low[k] * e * t, hi += s.high[k] * e * t;
  }
  *low = std::log(open_lo / lo);
  *high = std::log(open_hi / hi);
}

}  // namespace rangex
