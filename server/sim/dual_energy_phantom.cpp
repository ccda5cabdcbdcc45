#include "sim/dual_energy_phantom.h"

#include <cmath>

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

void render_wedge_lines(const DualEnergyRenderer& detector, const FanBeam& beam,
                        const WedgeLayout& w, uint64_t seed, std::vector<uint16_t>& low,
                        std::vector<uint16_t>& high) {
  const int P = beam.pixels, L = w.lines();
  low.assign(size_t(L) * P, 0);
  high.assign(size_t(L) * P, 0);
  // Each pixel's means and variances for each aluminium step (index 0: bare belt).
  struct Reading {
    double m_lo, m_hi, v_lo, v_hi;
  };
  std::vector<Reading> r(size_t(P) * (w.al_mm.size() + 1));
  for (size_t j = 0; j <= w.al_mm.size(); ++j)
    for (int p = 0; p < P; ++p) {
      RayMaterials m;
      const int i = (p - w.first_pixel) / w.step_pixels;
      const bool on = j > 0 && p >= w.first_pixel && p < w.last_pixel();
      // A ray through a slab of d mm travels d / cos(theta) in it (the fan's slant).
      const double slant = beam.slab_path_factor(p);
      if (on) m.a150 = w.a150_mm[size_t(i)] * slant, m.aluminium = w.al_mm[j - 1] * slant;
      Reading& q = r[j * size_t(P) + size_t(p)];
      detector.mean(m, &q.m_lo, &q.m_hi, &q.v_lo, &q.v_hi);
    }
  for (int l = 0; l < L; ++l) {
    Rng rng(seed, uint64_t(l), 0xde11);
    const size_t j = l < w.open_lines ? 0 : size_t((l - w.open_lines) / w.step_lines) + 1;
    for (int p = 0; p < P; ++p) {
      const Reading& q = r[j * size_t(P) + size_t(p)];
      const size_t o = size_t(l) * P + size_t(p);
      DualEnergyRenderer::draw(q.m_lo, q.m_hi, q.v_lo, q.v_hi, rng, &low[o], &high[o]);
    }
  }
}

}  // namespace rangex::sim
