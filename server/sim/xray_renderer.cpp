#include "sim/xray_renderer.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/ray_path.h"

namespace rangex::sim {

XrayRenderer::XrayRenderer(const LaneConfig& lane, XrayRenderParams p)
    : fb_(lane.xray),
      xray_y_(lane.laser.offset_mm + lane.xray.delay_lines * lane.encoder_step_mm),
      p_(p) {}

void XrayRenderer::render(const LaneScene& scene, double s, Rng& rng, uint16_t* line,
                          float* thickness) const {
  const double b = s - xray_y_;
  constexpr int kN = 1101;
  std::vector<float> h(kN);
  scene.slice(b, h.data(), kN);
  float top = 0;
  for (float v : h) top = std::max(top, v);
  const ProfileGrid grid{h.data(), nullptr, kN, kLaneX0Mm, kRasterPitchMm, top};
  // Fillets cut by this slice, for the attenuation coefficient and inclusions.
  std::vector<const Fillet*> here;
  for (const Fillet& f : scene.fillets())
    if (b >= f.b_min - 10 && b <= (f.ib0 + f.nb) * kRasterPitchMm + 10) here.push_back(&f);
  const double maxv = double((1 << fb_.bits) - 1);
  for (int i = 0; i < fb_.pixels; ++i) {
    const double xd = fb_.pixel_x(i), zd = fb_.pixel_z(i);
    const PathResult r = ray_path_length(grid, xd, zd, fb_.source_x_mm, fb_.source_z_mm);
    thickness[i] = float(r.length_mm);
    double att = 0;
    if (r.length_mm > 0) {
      // The ray crosses the meat close to its foot; the fillet under it gives mu.
      const double dz = fb_.source_z_mm - zd;
      const Vec3 o{xd, b, zd};
      const Vec3 d = Vec3{fb_.source_x_mm - xd, 0, dz}.normalized();
      const double xm = xd + (fb_.source_x_mm - xd) * (0.5 * top - zd) / dz;
      double mu = 0.03;
      for (const Fillet* f : here)
        if (f->height_at(xm, b) > 0 || f->height_at(xd, b) > 0) mu = f->mu_at(xm, b);
      att = mu * r.length_mm;
      for (const Fillet* f : here)
        for (const Inclusion& in : f->inclusions)
          if (std::abs(in.center.y - b) <= in.size_mm) att += in.dmu * in.chord(o, d);
    }
    const double mean = p_.open_beam_dn * std::exp(-att);
    const double photons = mean * p_.photons_per_dn;
    // Photon counts are large (> 1000), where the normal approximation of Poisson holds.
    const double counts = photons + std::sqrt(photons) * rng.normal();
    const double dn = counts / p_.photons_per_dn + p_.electronic_noise * rng.normal();
    line[i] = uint16_t(std::clamp(std::lround(dn), 0L, long(maxv)));
  }
}

}  // namespace rangex::sim
