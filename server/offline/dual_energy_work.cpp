#include "offline/dual_energy_work.h"

#include "calib/dual_energy_fit.h"
#include "sim/dual_energy_phantom.h"
#include "sim/rng.h"

namespace rangex {

DualEnergyCalibrated calibrate_dual_energy(int pixels_per_step) {
  DualEnergyCalibrated c{sim::DualEnergyRenderer{SandwichDetector{}}, {}, 0, 0};
  const WedgeScan scan = sim::simulate_wedge_scan(c.detector, 1, pixels_per_step);
  c.params = fit_dual_energy(scan, SandwichDetector{}, 0.05).params;
  c.open_low = scan.open_low, c.open_high = scan.open_high;
  return c;
}

DualEnergyBatch DualEnergyRays::batch() const {
  DualEnergyBatch b;
  b.low = low.data(), b.high = high.data(), b.open_low = open_low.data();
  b.open_high = open_high.data(), b.thickness = thickness.data(), b.use = use.data();
  b.pixels = pixels();
  return b;
}

void DualEnergyRays::add(const DualEnergyCalibrated& c, const sim::RayMaterials& r, int n,
                         double laser_mm, uint64_t seed) {
  sim::Rng rng(seed, 7);
  const double total = r.lean + r.fat + r.cartilage + r.tendon + r.bone;
  double m_lo, m_hi, v_lo, v_hi;
  c.detector.mean(r, &m_lo, &m_hi, &v_lo, &v_hi);
  for (int k = 0; k < n; ++k) {
    uint16_t lo, hi;
    sim::DualEnergyRenderer::draw(m_lo, m_hi, v_lo, v_hi, rng, &lo, &hi);
    low.push_back(lo), high.push_back(hi);
    open_low.push_back(float(c.open_low)), open_high.push_back(float(c.open_high));
    thickness.push_back(float(total + laser_mm * rng.normal()));
    use.push_back(1);
  }
}

DualEnergyRays mixed_dual_energy_rays(const DualEnergyCalibrated& c, int pixels, uint64_t seed) {
  DualEnergyRays rays;
  sim::Rng rng(seed, 0xde5);
  for (int p = 0; p < pixels; ++p) {
    sim::RayMaterials r;
    r.lean = 45 * rng.uniform();
    r.fat = 12 * rng.uniform() * rng.uniform();
    if (p % 3 == 0) r.bone = 4 * rng.uniform(), r.calcification = 0.3 + 0.7 * rng.uniform();
    if (p % 7 == 0) r.cartilage = 6 * rng.uniform();
    rays.add(c, r, 1, 0.05, seed + uint64_t(p));
    switch (p % 97) {
      case 11:
        rays.use.back() = 0;
        break;
      case 23:
        rays.low.back() = 0;
        break;
      case 31:
        rays.high.back() = 65535, rays.low.back() = 65535;
        break;
      case 47:
        rays.open_low.back() = 0;
        break;
      default:
        break;
    }
  }
  return rays;
}

}  // namespace rangex
