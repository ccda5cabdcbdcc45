#include "sim/camera_renderer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/error.h"
#include "sim/calib_objects.h"
#include "sim/stripe_profile.h"

namespace rangex::sim {

namespace {
struct Hit {
  double v = 0;
  Vec3 p;       // world point on the stripe
  Vec3 normal;  // surface normal (object frame == world frame up to the y flip)
  bool meat = false;
};
}  // namespace

CameraRenderer::CameraRenderer(const LaneConfig& lane, int camera, CameraRenderParams p)
    : cam_(lane.cameras[camera].model),
      laser_y_(lane.laser.offset_mm),
      width_(lane.frame_width),
      height_(lane.frame_height),
      p_(p),
      meat_kernel_(p.core_sigma_px, p.meat_tail_px),
      belt_kernel_(p.core_sigma_px, p.belt_tail_px) {
  if (std::abs(lane.laser.normal.y) < 0.9999)
    fail("the simulator renders a laser plane perpendicular to the belt only (normal ",
         lane.laser.normal.x, ", ", lane.laser.normal.y, ", ", lane.laser.normal.z, ")");
  // Scattered light leaves the meat on the side away from the camera; find which way
  // that runs in this camera's image.
  const Vec3 c = cam_.center();
  const Vec3 p0{0, laser_y_, 0};
  const Vec3 away{0, c.y > laser_y_ ? -1.0 : 1.0, 0};
  tail_sign_ = (cam_.project(p0 + away).y > cam_.project(p0).y ? 1 : -1) * p_.tail_direction;
  Rng rng(0x0153, camera);
  noise_.resize(1 << 16);
  for (auto& n : noise_)
    n = uint8_t(std::clamp(std::lround(p_.background + p_.read_noise * rng.normal()), 0L, 255L));
}

template <typename Scene>
void CameraRenderer::render(const Scene& scene, double s, Rng& rng, uint8_t* frame,
                            float* truth_row) const {
  const size_t npx = size_t(width_) * height_;
  // Background and read noise from the pre-drawn table at random offsets.
  for (size_t i = 0; i < npx;) {
    const uint64_t r = rng.next();
    const size_t n = std::min<size_t>(256 + ((r >> 16) & 0xff), npx - i);
    const size_t off = (r & 0xffff) % (noise_.size() - n);
    std::memcpy(frame + i, &noise_[off], n);
    i += n;
  }
  std::fill(truth_row, truth_row + width_, std::numeric_limits<float>::quiet_NaN());

  const double b_laser = s - laser_y_;
  constexpr int kN = 1101;  // slice samples over the lane, kLaneX0Mm .. +220 mm
  std::vector<float> h(kN);
  scene.slice(b_laser, h.data(), kN);
  std::vector<Vec2> px(kN);
  for (int k = 0; k < kN; ++k)
    px[k] = cam_.project({kLaneX0Mm + k * kRasterPitchMm, laser_y_, double(h[k])});

  const Vec3 cc = cam_.center();
  // Only fillets within reach of the lines of sight can hide the stripe.
  const float near_top = scene.max_height(b_laser - 100, b_laser + 100);
  const bool fillets_near = near_top > 0;
  // The points of the surface that project onto a column, in the order the segments give
  // them; which of them the camera sees is decided for all at once (below), then the first
  // visible highest one of each column is kept as before.
  struct Candidate {
    int c, k;
    Vec3 P;
    Vec2 q;
  };
  std::vector<Candidate> cand;
  cand.reserve(size_t(width_) + 64);
  for (int k = 0; k + 1 < kN; ++k) {
    const double ua = px[k].x, ub = px[k + 1].x;
    if (ua == ub) continue;
    const int c0 = int(std::ceil(std::min(ua, ub))), c1 = int(std::floor(std::max(ua, ub)));
    for (int c = std::max(c0, 0); c <= std::min(c1, width_ - 1); ++c) {
      if (c == std::max(ua, ub)) continue;  // each column belongs to one segment
      // Point on the straight surface segment that projects exactly onto column c: secant
      // refinement of the linear guess through the exact projection.
      const Vec3 A{kLaneX0Mm + k * kRasterPitchMm, laser_y_, double(h[k])};
      const Vec3 B{A.x + kRasterPitchMm, laser_y_, double(h[k + 1])};
      double t0 = 0, t1 = 1, f0 = ua - c, f1 = ub - c;
      double t = f0 / (f0 - f1);
      for (int it = 0; it < 4; ++it) {
        const double ft = cam_.project(A + (B - A) * t).x - c;
        if (std::abs(ft) < 1e-9) break;
        if ((ft < 0) == (f0 < 0))
          t0 = t, f0 = ft;
        else
          t1 = t, f1 = ft;
        t = t0 + (t1 - t0) * f0 / (f0 - f1);
      }
      const Vec3 P = A + (B - A) * t;
      const Vec2 q = cam_.project(P);
      if (q.y < -0.5 || q.y > height_ - 0.5) continue;
      cand.push_back({c, k, P, q});
    }
  }

  // Occlusion: walk from each point toward the camera over the scene's surface. The step
  // grows with the clearance above the surface (fillet slopes stay well below 3, so half the
  // clearance cannot skip a crest). Each walk is a chain of dependent height lookups; a
  // group of walks advanced together overlaps their latencies (each walk's own steps are
  // unchanged).
  std::vector<uint8_t> visible(cand.size(), 1);
  if (fillets_near) {
    constexpr size_t kGroup = 8;
    for (size_t g = 0; g < cand.size(); g += kGroup) {
      const size_t n = std::min(kGroup, cand.size() - g);
      Vec3 d[kGroup];
      double dist[kGroup];
      bool walking[kGroup];
      size_t left = n;
      for (size_t i = 0; i < n; ++i) {
        const Vec3& P = cand[g + i].P;
        d[i] = (cc - P).normalized();
        dist[i] = 0.3;
        walking[i] = true;
        // A walk whose every step would land over bare belt finds the point visible (its
        // clearance is its own height): it need not be taken. Its steps stay on the segment
        // up to the height where it stops.
        if (d[i].z > 0) {
          const Vec3 E = P + d[i] * ((near_top + 0.1 - P.z) / d[i].z);
          if (scene.bare(std::min(P.x, E.x), std::max(P.x, E.x), s - std::max(P.y, E.y),
                         s - std::min(P.y, E.y)))
            walking[i] = false, --left;
        }
      }
      while (left > 0) {
        for (size_t i = 0; i < n; ++i) {
          if (!walking[i]) continue;
          const Vec3 Q = cand[g + i].P + d[i] * dist[i];
          if (Q.z > near_top + 0.1) {
            walking[i] = false;
            --left;
            continue;
          }
          const double clearance = Q.z - scene.height(Q.x, s - Q.y);
          if (clearance < -1e-3) {
            visible[g + i] = 0;
            walking[i] = false;
            --left;
            continue;
          }
          dist[i] += std::max(0.3, 0.5 * clearance);
        }
      }
    }
  }

  std::vector<Hit> hits(width_);
  std::vector<uint8_t> has(width_, 0);
  for (size_t j = 0; j < cand.size(); ++j) {
    if (!visible[j]) continue;
    const auto& [c, k, P, q] = cand[j];
    if (has[c] && hits[c].p.z >= P.z) continue;
    const double slope = (double(h[k + 1]) - h[k]) / kRasterPitchMm;
    // Along-belt slope from the neighbouring slices sets how the surface faces the camera.
    const double dhdb = (scene.height(P.x, b_laser + 0.4) - scene.height(P.x, b_laser - 0.4)) / 0.8;
    Hit hit;
    hit.v = q.y;
    hit.p = P;
    hit.normal = Vec3{-slope, dhdb, 1.0}.normalized();  // world y = s - b flips d/db
    hit.meat = scene.is_meat(P);
    hits[c] = hit;
    has[c] = 1;
  }

  for (int c = 0; c < width_; ++c) {
    if (!has[c]) continue;
    const Hit& hit = hits[c];
    truth_row[c] = float(hit.v);
    const Vec3 view = (cc - hit.p).normalized();
    const double facing = std::clamp(hit.normal.dot(view), 0.0, 1.0);
    double amp, tail, lambda;
    if (hit.meat) {
      amp = p_.meat_amplitude * (0.75 + 0.25 * facing);
      tail = (p_.meat_tail_base + p_.meat_tail_gain * (1 - facing)) * scene.scatter_scale(hit.p, s);
      lambda = p_.meat_tail_px;
    } else {
      amp = p_.belt_amplitude;
      if (p_.belt_texture > 0) {
        // A woven belt, wet in patches: reflectance varying on 2-7 mm scales.
        const double b = s - hit.p.y;
        amp *= 1 + p_.belt_texture * std::sin(2.7 * hit.p.x + 0.9 * b) *
                       std::cos(0.9 * hit.p.x - 1.7 * b);
      }
      tail = p_.belt_tail;
      lambda = p_.belt_tail_px;
    }
    amp *= std::exp(p_.column_speckle * rng.normal());
    double sigma = p_.core_sigma_px + p_.defocus_px_per_mm * std::max(0.0, hit.p.z);
    if (hit.meat && p_.glint_probability > 0 && rng.chance(p_.glint_probability)) {
      amp *= rng.uniform(4, 10);  // a specular glint off a wet spot saturates the sensor
      sigma *= 0.6;
    }
    const double rho =
        p_.speckle_correlation_px > 0 ? std::exp(-1 / p_.speckle_correlation_px) : 0.0;
    add_stripe(frame + c, height_, width_,
               {hit.v, amp, sigma, tail, lambda, tail_sign_, p_.speckle, rho}, rng,
               hit.meat ? &meat_kernel_ : &belt_kernel_);
  }
}

template void CameraRenderer::render(const LaneScene&, double, Rng&, uint8_t*, float*) const;
template void CameraRenderer::render(const CalibScene&, double, Rng&, uint8_t*, float*) const;

}  // namespace rangex::sim
