#include "sim/xray_renderer.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "core/ray_path.h"

namespace rangex::sim {

namespace {
constexpr int kSlice = 1101;  // slice samples over the lane, kLaneX0Mm .. +220 mm

struct Slice {
  std::vector<float> h = std::vector<float>(kSlice);
  float top = 0;
  std::vector<const Fillet*> here;  // fillets cut by it, for mu and inclusions
  std::vector<int> raised = std::vector<int>(kSlice + 1);  // samples above the belt before each
};

void cut(const LaneScene& scene, double b, Slice& s) {
  scene.slice(b, s.h.data(), kSlice);
  s.top = 0;
  for (float v : s.h) s.top = std::max(s.top, v);
  for (int k = 0; k < kSlice; ++k) s.raised[size_t(k) + 1] = s.raised[size_t(k)] + (s.h[k] != 0);
  s.here.clear();
  for (const Fillet& f : scene.fillets())
    if (b >= f.b_min - 10 && b <= (f.ib0 + f.nb) * kRasterPitchMm + 10) s.here.push_back(&f);
}

// Whether a ray meets only samples on the belt (height 0) on its way up to the slice's top.
// ray_path_length then sums nothing but zeros: its length is exactly 0 without the walk. The
// cells it would visit lie between its feet at the belt and at the top, 3 cells to spare.
bool over_belt_only(const Slice& s, double xd, double zd, double xs, double zs) {
  const double slope = (xs - xd) / (zs - zd);
  const double top = std::max<double>(s.top, 1e-6);
  const double c0 = (xd + slope * (0 - zd) - kLaneX0Mm) / kRasterPitchMm,
               c1 = (xd + slope * (top - zd) - kLaneX0Mm) / kRasterPitchMm;
  const double lo = std::clamp(std::floor(std::min(c0, c1)) - 3, 0.0, double(kSlice)),
               hi = std::clamp(std::floor(std::max(c0, c1)) + 4, 0.0, double(kSlice));
  return s.raised[size_t(hi)] == s.raised[size_t(lo)];
}

// ln(I0 / I) of one ray through a slice, and the meat's path length.
double slice_attenuation(const Slice& s, double b, double xd, double zd, double xs, double zs,
                         double* path) {
  if (over_belt_only(s, xd, zd, xs, zs)) {
    *path = 0;
    return 0;
  }
  const ProfileGrid grid{s.h.data(), nullptr, kSlice, kLaneX0Mm, kRasterPitchMm, s.top};
  const PathResult r = ray_path_length(grid, xd, zd, xs, zs);
  *path = r.length_mm;
  if (r.length_mm <= 0) return 0;
  // The ray crosses the meat close to its foot; the fillet under it gives mu.
  const double dz = zs - zd;
  const Vec3 o{xd, b, zd};
  const Vec3 d = Vec3{xs - xd, 0, dz}.normalized();
  const double xm = xd + (xs - xd) * (0.5 * s.top - zd) / dz;
  double mu = 0.03;
  for (const Fillet* f : s.here)
    if (f->height_at(xm, b) > 0 || f->height_at(xd, b) > 0) mu = f->mu_at(xm, b);
  double att = mu * r.length_mm;
  for (const Fillet* f : s.here)
    for (const Inclusion& in : f->inclusions)
      if (std::abs(in.center.y - b) <= in.size_mm) att += in.dmu * in.chord(o, d);
  return att;
}
// The materials one ray crosses in a slice (dual energy), as slice_attenuation sees them:
// what an inclusion's chord holds takes the meat's place; the meat is lean and fat by the
// fillet's fat share and its marbling, as dense as its texture makes it.
RayMaterials slice_materials(const Slice& s, double b, double xd, double zd, double xs, double zs,
                             double* path) {
  const ProfileGrid grid{s.h.data(), nullptr, kSlice, kLaneX0Mm, kRasterPitchMm, s.top};
  const PathResult r = ray_path_length(grid, xd, zd, xs, zs);
  *path = r.length_mm;
  RayMaterials m;
  m.calcification = 1;  // bone below is cortical; its uncalcified part goes to cartilage
  if (r.length_mm <= 0) return m;
  const double dz = zs - zd;
  const Vec3 o{xd, b, zd};
  const Vec3 d = Vec3{xs - xd, 0, dz}.normalized();
  const double xm = xd + (xs - xd) * (0.5 * s.top - zd) / dz;
  const Fillet* under = nullptr;
  for (const Fillet* f : s.here)
    if (f->height_at(xm, b) > 0 || f->height_at(xd, b) > 0) under = f;
  double meat = r.length_mm;
  for (const Fillet* f : s.here)
    for (const Inclusion& in : f->inclusions) {
      if (std::abs(in.center.y - b) > in.size_mm) continue;
      const double c = in.chord(o, d);
      if (c <= 0) continue;
      meat -= c;
      switch (in.kind) {
        case Inclusion::kBone:
          m.bone += in.calcification * c;
          m.cartilage += (1 - in.calcification) * c;
          break;
        case Inclusion::kCartilage:
          // Soft tissue at cartilage's density (1.10 g/cm3, muscle's mu/rho): 5 % more than
          // lean, not the 15-35 % the single-energy renderer's contrast gives it. Tissue that
          // attenuates that much more holds calcium, which is what dual energy measures.
          m.cartilage += c;
          break;
        case Inclusion::kFat:
          m.fat += c;
          break;
        case Inclusion::kAir:
          break;
      }
    }
  meat = std::max(0.0, meat);
  double phi = 0.05, density = 1;
  if (under) {
    phi = std::clamp(under->fat_share + (1 - under->fat_share) * under->rough.fat_at(xm, b), 0.0,
                     1.0);
    // The texture (fibres, the sinusoid) as density; the fillet's own mu is composition,
    // which the fat share carries here.
    density = under->mu_at(xm, b) / under->mu / (1 + under->rough.at(xm, b)) *
              (1 + under->rough.density_at(xm, b));
  }
  m.lean += meat * (1 - phi) * density;
  m.fat += meat * phi * density;
  return m;
}
}  // namespace

XrayRenderer::XrayRenderer(const LaneConfig& lane, XrayRenderParams p, XrayPhysics physics)
    : fb_(lane.xray),
      xray_y_(lane.laser.offset_mm + lane.xray.delay_lines * lane.encoder_step_mm),
      step_(lane.encoder_step_mm),
      p_(p),
      ph_(physics) {
  // The detector's own pattern: fixed for the lane, whatever the plant's seed.
  if (ph_.flat_field_std > 0) {
    Rng r(0xf1a7f1e1d, uint64_t(lane.id));
    gain_.resize(size_t(fb_.pixels));
    for (float& g : gain_) g = float(1 + ph_.flat_field_std * r.normal());
  }
  if (lane.xray.energies == 2) {
    DualEnergyRenderParams dp;
    dp.electronic_noise = p.electronic_noise;
    de_ = std::make_shared<const DualEnergyRenderer>(lane.xray.sandwich, dp);
    if (ph_.flat_field_std > 0) {
      Rng r(0xf1a7f1e1d, uint64_t(lane.id), 2);
      gain_high_.resize(size_t(fb_.pixels));
      for (float& g : gain_high_) g = float(1 + ph_.flat_field_std * r.normal());
    }
  }
}

double XrayRenderer::plane_y(double x, double z) const {
  return xray_y_ + ph_.plane_offset_lines * step_ + x * std::tan(ph_.alpha_deg * M_PI / 180) +
         z * std::tan(ph_.beta_deg * M_PI / 180);
}

void XrayRenderer::render(const LaneScene& scene, double s, Rng& rng, uint16_t* line,
                          float* thickness, uint16_t* high) const {
  const double maxv = double((1 << fb_.bits) - 1);
  const double ripple = 1 + ph_.ripple * std::sin(2 * M_PI * s / (step_ * ph_.ripple_lines) + 0.7);
  auto emit = [&](int i, double mean) {
    mean *= ripple * (gain_.empty() ? 1.0 : gain_[size_t(i)]);
    const double photons = mean * p_.photons_per_dn;
    // Photon counts are large (> 1000), where the normal approximation of Poisson holds.
    const double counts = photons + std::sqrt(photons) * rng.normal();
    const double dn = counts / p_.photons_per_dn + p_.electronic_noise * rng.normal();
    line[i] = uint16_t(std::clamp(std::lround(dn), 0L, long(maxv)));
  };
  // Dual energy: each layer's reading, its variance scaled with it (the tube's ripple and
  // the flat-field residual scale the photons).
  auto emit2 = [&](int i, double m_lo, double m_hi, double v_lo, double v_hi) {
    const double g_lo = ripple * (gain_.empty() ? 1.0 : gain_[size_t(i)]),
                 g_hi = ripple * (gain_high_.empty() ? 1.0 : gain_high_[size_t(i)]);
    uint16_t lo, hi;
    DualEnergyRenderer::draw(m_lo * g_lo, m_hi * g_hi, v_lo * g_lo * g_lo, v_hi * g_hi * g_hi, rng,
                             &lo, &hi);
    line[i] = std::min<uint16_t>(lo, uint16_t(maxv));
    if (high) high[i] = std::min<uint16_t>(hi, uint16_t(maxv));
  };
  auto harden = [&](double att) { return att / (1 + ph_.hardening * att); };
  const bool plain = ph_.detector_sigma_px == 0 && ph_.focal_spot_sigma_mm == 0 &&
                     ph_.plane_offset_lines == 0 && ph_.alpha_deg == 0 && ph_.beta_deg == 0;
  if (plain) {
    Slice sl;
    const double b = s - xray_y_;
    cut(scene, b, sl);
    for (int i = 0; i < fb_.pixels; ++i) {
      double path = 0;
      if (de_) {
        const RayMaterials m = slice_materials(sl, b, fb_.pixel_x(i), fb_.pixel_z(i),
                                               fb_.source_x_mm, fb_.source_z_mm, &path);
        double lo, hi, v_lo, v_hi;
        de_->mean(m, &lo, &hi, &v_lo, &v_hi);
        thickness[i] = float(path);
        emit2(i, lo, hi, v_lo, v_hi);
        continue;
      }
      const double att = slice_attenuation(sl, b, fb_.pixel_x(i), fb_.pixel_z(i), fb_.source_x_mm,
                                           fb_.source_z_mm, &path);
      thickness[i] = float(path);
      emit(i, p_.open_beam_dn * std::exp(-harden(att)));
    }
    return;
  }
  // Each pixel integrates its aperture (four sub-samples across) and the belt's travel over
  // the line (four along); the belt position the X-ray plane cuts depends on where the ray
  // crosses the meat (10 mm up is taken for every ray), so slices are cut on a 0.05 mm grid
  // of belt positions and shared.
  constexpr int kSub = 4;
  constexpr double kMidZ = 10, kGrid = 0.05;
  const int n = fb_.pixels, nf = n * kSub;
  std::map<long, Slice> slices;
  // I: the (low layer's) reading on the fine grid; dual energy adds the high layer's and
  // both variances.
  std::vector<double> I(nf), path_f(nf), I_hi, V_lo, V_hi;
  if (de_) I_hi.assign(size_t(nf), 0.0), V_lo = I_hi, V_hi = I_hi;
  for (int f = 0; f < nf; ++f) {
    const double u = (f + 0.5) / kSub - 0.5;
    const double xd = fb_.first_pixel_x_mm + fb_.pitch_x() * u,
                 zd = fb_.detector_z_mm + fb_.pitch_z() * u;
    const double xm = xd + (fb_.source_x_mm - xd) * (kMidZ - zd) / (fb_.source_z_mm - zd);
    I[f] = path_f[f] = 0;
    for (int j = 0; j < kSub; ++j) {
      const double travel = step_ * ((j + 0.5) / kSub - 0.5);
      const long key = std::lround((s + travel - plane_y(xm, kMidZ)) / kGrid);
      auto it = slices.find(key);
      if (it == slices.end()) {
        it = slices.emplace(key, Slice{}).first;
        cut(scene, key * kGrid, it->second);
      }
      double path = 0;
      if (de_) {
        const RayMaterials m = slice_materials(it->second, key * kGrid, xd, zd, fb_.source_x_mm,
                                               fb_.source_z_mm, &path);
        double lo, hi, v_lo, v_hi;
        de_->mean(m, &lo, &hi, &v_lo, &v_hi);
        I[f] += lo / kSub, I_hi[size_t(f)] += hi / kSub;
        V_lo[size_t(f)] += v_lo / kSub, V_hi[size_t(f)] += v_hi / kSub;
      } else {
        const double att = slice_attenuation(it->second, key * kGrid, xd, zd, fb_.source_x_mm,
                                             fb_.source_z_mm, &path);
        I[f] += p_.open_beam_dn * std::exp(-harden(att)) / kSub;
      }
      // The truth: the path at the line's own position (its middle).
      if (j == kSub / 2) path_f[f] = path;
    }
  }
  // Blur across the detector, on the fine grid: the line-spread function and the focal
  // spot's image, which grows with the height of what casts the shadow (taken at half the
  // path's length above the belt).
  const double mag_den = fb_.source_z_mm;
  std::vector<double> weights;  // the blur's weight at each offset, for the sigma below
  double weights_sigma = -1;
  int R = 0;
  for (int i = 0; i < n; ++i) {
    double path = 0;
    for (int k = 0; k < kSub; ++k) path += path_f[i * kSub + k] / kSub;
    thickness[i] = float(path);
    const double z = 0.5 * path;
    const double focal_px =
        ph_.focal_spot_sigma_mm * (z - fb_.detector_z_mm) / (mag_den - z) / fb_.pitch_mm;
    const double sigma = std::hypot(ph_.detector_sigma_px, focal_px) * kSub;
    if (sigma >= 0.05 && sigma != weights_sigma) {  // most pixels share the belt's sigma
      R = int(std::ceil(4 * sigma));
      weights.resize(size_t(2 * R + 1));
      for (int j = -R; j <= R; ++j)
        weights[size_t(j + R)] = std::exp(-0.5 * j * j / (sigma * sigma));
      weights_sigma = sigma;
    }
    // The pixel's mean of each fine-grid array (the blur's weights, else its aperture).
    auto pixel_mean = [&](const std::vector<double>& v) {
      double mean = 0;
      if (sigma < 0.05) {
        for (int k = 0; k < kSub; ++k) mean += v[size_t(i * kSub + k)] / kSub;
        return mean;
      }
      double wsum = 0;
      for (int k = 0; k < kSub; ++k)
        for (int j = -R; j <= R; ++j) {
          const int f = std::clamp(i * kSub + k + j, 0, nf - 1);
          const double w = weights[size_t(j + R)];
          mean += w * v[size_t(f)], wsum += w;
        }
      return mean / wsum;
    };
    if (de_)
      emit2(i, pixel_mean(I), pixel_mean(I_hi), pixel_mean(V_lo), pixel_mean(V_hi));
    else
      emit(i, pixel_mean(I));
  }
}

}  // namespace rangex::sim
