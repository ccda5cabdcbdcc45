#include "sim/calib_xray_renderer.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace rangex::sim {

namespace {

// Length of the segment a + t (c - a), t in [0, 1], inside the box (object coordinates).
double box_path(const CalibBox& k, Vec3 a, Vec3 c) {
  double lx, lb;  // into the box's own frame (a turn about the vertical)
  k.local(a.x, a.y, lx, lb);
  a.x = lx, a.y = lb;
  k.local(c.x, c.y, lx, lb);
  c.x = lx, c.y = lb;
  double t0 = 0, t1 = 1;
  const double lo[3] = {k.x0, k.b0, k.z0}, hi[3] = {k.x1, k.b1, k.z1};
  const double o[3] = {a.x, a.y, a.z}, d[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-15) {
      if (o[i] < lo[i] || o[i] > hi[i]) return 0;
      continue;
    }
    double ta = (lo[i] - o[i]) / d[i], tb = (hi[i] - o[i]) / d[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 >= t1) return 0;
  }
  return (t1 - t0) * (c - a).norm();
}

double pin_path(const CalibPin& p, const Vec3& a, const Vec3& c) {
  const Vec3 d = c - a;
  const double ox = a.x - p.x, oz = a.z - p.z;
  const double A = d.x * d.x + d.z * d.z, B = 2 * (ox * d.x + oz * d.z),
               C = ox * ox + oz * oz - p.radius * p.radius;
  const double disc = B * B - 4 * A * C;
  if (A < 1e-15 || disc <= 0) return 0;
  const double sq = std::sqrt(disc);
  double t0 = std::max(0.0, (-B - sq) / (2 * A)), t1 = std::min(1.0, (-B + sq) / (2 * A));
  // Clip to the pin's length along the belt.
  if (std::abs(d.y) > 1e-15) {
    double ta = (p.b0 - a.y) / d.y, tb = (p.b1 - a.y) / d.y;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  } else if (a.y < p.b0 || a.y > p.b1) {
    return 0;
  }
  return t1 > t0 ? (t1 - t0) * d.norm() : 0;
}

}  // namespace

CalibXrayRenderer::CalibXrayRenderer(const LaneConfig& lane, XrayOptics optics, XrayRenderParams p)
    : fb_(lane.xray),
      o_(optics),
      p_(p),
      tan_alpha_(std::tan(optics.alpha_rad)),
      tan_beta_(std::tan(optics.beta_rad)) {
  if (std::isnan(o_.plane_y_mm))
    o_.plane_y_mm = lane.laser.offset_mm + lane.xray.delay_lines * lane.encoder_step_mm;
}

double CalibXrayRenderer::plane_y(double x, double z) const {
  return o_.plane_y_mm + x * tan_alpha_ + z * tan_beta_;
}

void CalibXrayRenderer::render(const CalibScene& scene, double s, Rng& rng, uint16_t* line) const {
  // Focal spot: nine sub-sources across the fan with Gaussian weights.
  constexpr int kSpots = 9;
  double off[kSpots], w[kSpots], wsum = 0;
  for (int k = 0; k < kSpots; ++k) {
    off[k] = o_.focal_spot_sigma_mm * (-2.4 + 4.8 * k / (kSpots - 1));
    w[k] = o_.focal_spot_sigma_mm > 0 ? std::exp(-0.5 * std::pow(-2.4 + 4.8 * k / (kSpots - 1), 2))
                                      : (k == kSpots / 2 ? 1.0 : 0.0);
    wsum += w[k];
  }
  // Each pixel integrates its aperture: four sub-samples, blurred on the fine grid by the
  // line-spread function, then averaged.
  constexpr int kSub = 4;
  const int n = fb_.pixels, nf = n * kSub;
  // Object coordinates: b = belt offset - y. The sub-sources and the detector's sub-samples
  // are the ends of every ray of this line.
  Vec3 S[kSpots];
  for (int k = 0; k < kSpots; ++k) {
    const double xs = fb_.source_x_mm + off[k], zs = fb_.source_z_mm;
    S[k] = Vec3{xs, s - plane_y(xs, zs), zs};
  }
  std::vector<Vec3> D(nf);
  for (int f = 0; f < nf; ++f) {
    const double u = (f + 0.5) / kSub - 0.5;
    const double xd = fb_.first_pixel_x_mm + fb_.pitch_x() * u,
                 zd = fb_.detector_z_mm + fb_.pitch_z() * u;
    D[f] = Vec3{xd, s - plane_y(xd, zd), zd};
  }
  // Only objects whose stretch of belt the line's rays reach can attenuate them: a ray whose
  // ends both lie beyond an object along the belt misses it (its path is exactly 0, so
  // leaving it out changes no sum).
  double lo = HUGE_VAL, hi = -HUGE_VAL;
  for (int k = 0; k < kSpots; ++k)
    if (w[k] != 0) lo = std::min(lo, S[k].y), hi = std::max(hi, S[k].y);
  for (const Vec3& d : D) lo = std::min(lo, d.y), hi = std::max(hi, d.y);
  std::vector<const CalibBox*> boxes;
  for (const CalibBox& b : scene.boxes)
    if (b.may_reach(-HUGE_VAL, HUGE_VAL, lo, hi)) boxes.push_back(&b);
  std::vector<const CalibPin*> pins;
  for (const CalibPin& p : scene.pins)
    if (p.b1 >= lo && p.b0 <= hi) pins.push_back(&p);
  std::vector<double> I(nf);
  for (int f = 0; f < nf; ++f) {
    double sum = 0;
    for (int k = 0; k < kSpots; ++k) {
      if (w[k] == 0) continue;
      double att = 0;
      for (const CalibBox* b : boxes) att += b->mu_per_mm * box_path(*b, D[f], S[k]);
      for (const CalibPin* p : pins) att += p->mu_per_mm * pin_path(*p, D[f], S[k]);
      sum += w[k] * std::exp(-att);
    }
    I[f] = p_.open_beam_dn * sum / wsum;
  }
  if (o_.detector_sigma_px > 0) {
    const double sf = o_.detector_sigma_px * kSub;
    const int R = int(std::ceil(4 * sf));
    std::vector<double> k(2 * R + 1), out(nf);
    double ks = 0;
    for (int j = -R; j <= R; ++j) ks += k[j + R] = std::exp(-0.5 * j * j / (sf * sf));
    for (int f = 0; f < nf; ++f) {
      double a = 0;
      for (int j = -R; j <= R; ++j) a += k[j + R] * I[std::clamp(f + j, 0, nf - 1)];
      out[f] = a / ks;
    }
    I.swap(out);
  }
  const double maxv = double((1 << fb_.bits) - 1);
  for (int i = 0; i < n; ++i) {
    double mean = 0;
    for (int k = 0; k < kSub; ++k) mean += I[i * kSub + k] / kSub;
    const double photons = mean * p_.photons_per_dn;
    const double counts = photons + std::sqrt(photons) * rng.normal();
    const double dn = counts / p_.photons_per_dn + p_.electronic_noise * rng.normal();
    line[i] = uint16_t(std::clamp(std::lround(dn), 0L, long(maxv)));
  }
}

}  // namespace rangex::sim
