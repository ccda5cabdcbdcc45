#include "sim/dual_energy_phantom.h"

namespace rangex::sim {

WedgeScan simulate_wedge_scan(const DualEnergyRenderer& detector, uint64_t seed,
                              int pixels_per_step) {
  WedgeScan scan;
  Rng rng(seed, 0xde);
  auto step = [&](double a150, double al) {
    RayMaterials r;
    r.a150 = a150, r.aluminium = al;
    double s_lo = 0, s_hi = 0, q_lo = 0, q_hi = 0, m_lo, m_hi, v_lo, v_hi;
    detector.mean(r, &m_lo, &m_hi, &v_lo, &v_hi);
    for (int k = 0; k < pixels_per_step; ++k) {
      uint16_t lo, hi;
      DualEnergyRenderer::draw(m_lo, m_hi, v_lo, v_hi, rng, &lo, &hi);
      s_lo += lo, s_hi += hi, q_lo += double(lo) * lo, q_hi += double(hi) * hi;
    }
    const double n = pixels_per_step;
    WedgeStep s;
    s.a150_mm = a150, s.al_mm = al, s.samples = pixels_per_step;
    s.low = s_lo / n, s.high = s_hi / n;
    s.var_low = (q_lo - s_lo * s_lo / n) / (n - 1);
    s.var_high = (q_hi - s_hi * s_hi / n) / (n - 1);
    return s;
  };
  const WedgeStep open = step(0, 0);
  scan.open_low = open.low, scan.open_high = open.high;
  for (double a = 0; a <= 60 + 1e-9; a += 5)
    for (double b : {0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0}) scan.steps.push_back(step(a, b));
  return scan;
}

}  // namespace rangex::sim
