#include "sim/fillet.h"

#include <algorithm>
#include <cmath>

namespace rangex::sim {

namespace {
constexpr double kPi = 3.14159265358979323846;

Mat3 rotation_zx(double yaw, double tilt) {
  const double cy = std::cos(yaw), sy = std::sin(yaw), ct = std::cos(tilt), st = std::sin(tilt);
  Mat3 rz, rx;
  rz.m = {cy, -sy, 0, sy, cy, 0, 0, 0, 1};
  rx.m = {1, 0, 0, 0, ct, -st, 0, st, ct};
  return rz * rx;
}

// Shape of one fillet in its own frame (s along its length, t across).
struct Shape {
  double L, W, H, p, taper, thick_end;
  double harm_a[4], harm_p[4];
  double irr_a[3], irr_ks[3], irr_kt[3], irr_p[3];
  // A thin flap grown from one side (flap_h > 0): centred at s = flap_s, reaching flap_len
  // beyond the outline on the side flap_side; a folded end (fold_h > 0): a second layer
  // over s > fold_s, whose edge is a step.
  double flap_h = 0, flap_s = 0, flap_half = 0, flap_len = 0, flap_side = 1;
  double fold_h = 0, fold_s = 0;
  double r_reach = 0;  // above 1 + sum(harm_a) by more than the sum's rounding (set_reach)

  void set_reach() { r_reach = (1 + harm_a[0] + harm_a[1] + harm_a[2] + harm_a[3]) * (1 + 1e-9); }

  double flap(double s, double t, double half_w) const {
    if (flap_h <= 0) return 0;
    const double ds = std::abs(s - flap_s) / flap_half, dt = flap_side * t - 0.85 * half_w;
    if (ds >= 1 || dt < 0 || dt > flap_len) return 0;
    return flap_h * std::sqrt(1 - ds * ds) * (1 - 0.6 * dt / flap_len);
  }

  double height(double s, double t) const {
    const double sn = s / (0.5 * L);
    const double half_w = 0.5 * W * (1 + taper * sn);
    const double tn = t / half_w;
    const double r = std::sqrt(sn * sn + tn * tn);
    // Beyond the largest radius the harmonics can reach, rho >= 1 whatever they sum to:
    // the same answer without the trigonometry (most of the raster's box is outside).
    if (r > r_reach) return flap(s, t, half_w);
    const double phi = std::atan2(tn, sn);
    double R = 1;
    for (int k = 0; k < 4; ++k) R += harm_a[k] * std::cos((k + 2) * phi + harm_p[k]);
    const double rho = r / R;
    if (rho >= 1) return flap(s, t, half_w);
    double irr = 1;
    for (int k = 0; k < 3; ++k)
      irr += irr_a[k] * std::sin(irr_ks[k] * s + irr_kt[k] * t + irr_p[k]);
    const double h = std::max(
        0.0, H * std::pow(1 - rho * rho, p) * (1 + thick_end * sn) * irr / (1 + thick_end));
    return std::max(h + (fold_h > 0 && s > fold_s && h > 0.5 ? fold_h : 0.0), flap(s, t, half_w));
  }
};
}  // namespace

double Inclusion::chord(const Vec3& o, const Vec3& d) const {
  const Vec3 lo = to_local * (o - center), ld = to_local * d;
  const Vec3 q{lo.x / semi.x, lo.y / semi.y, lo.z / semi.z};
  const Vec3 e{ld.x / semi.x, ld.y / semi.y, ld.z / semi.z};
  const double a = e.dot(e), b = 2 * q.dot(e), c = q.dot(q) - 1;
  const double disc = b * b - 4 * a * c;
  if (disc <= 0) return 0;
  return std::sqrt(disc) / a;  // (t2 - t1) with |d| = 1
}

float Fillet::height_at(double x, double b) const {
  const double fx = (x - kLaneX0Mm) / kRasterPitchMm - ix0;
  const double fb = b / kRasterPitchMm - ib0;
  if (fx < 0 || fb < 0 || fx >= nx - 1 || fb >= nb - 1) return 0;
  const int i = int(fx), j = int(fb);
  const float u = float(fx - i), v = float(fb - j);
  const float* r0 = &height[size_t(j) * nx + i];
  const float* r1 = r0 + nx;
  return (1 - v) * ((1 - u) * r0[0] + u * r0[1]) + v * ((1 - u) * r1[0] + u * r1[1]);
}

double Fillet::mu_at(double x, double b) const {
  return mu *
         (1 + texture_amp * std::sin(texture_kx * x + texture_phase) *
                  std::cos(texture_kb * b - texture_phase)) *
         (1 + rough.at(x, b));
}

namespace {

// The outline and profile of one fillet, in its own frame.
Shape draw_shape(Rng& rng, Rng& phys, const FilletParams& prm) {
  Shape sh;
  sh.L = rng.uniform(120, 200);
  sh.W = rng.uniform(60, 100);
  sh.H = rng.uniform(12, 45);
  sh.p = rng.uniform(0.9, 1.2);
  sh.taper = rng.uniform(0.1, 0.3) * (rng.chance(0.5) ? 1 : -1);
  sh.thick_end = rng.uniform(0.0, 0.25) * (sh.taper > 0 ? 1 : -1);
  for (int k = 0; k < 4; ++k) {
    sh.harm_a[k] = rng.uniform(0, 0.05);
    sh.harm_p[k] = rng.uniform(0, 2 * kPi);
  }
  for (int k = 0; k < 3; ++k) {
    sh.irr_a[k] = rng.uniform(0.01, 0.035);
    sh.irr_ks[k] = 2 * kPi / rng.uniform(20, 60) * (rng.chance(0.5) ? 1 : -1);
    sh.irr_kt[k] = 2 * kPi / rng.uniform(20, 60) * (rng.chance(0.5) ? 1 : -1);
    sh.irr_p[k] = rng.uniform(0, 2 * kPi);
  }
  sh.set_reach();
  // Steep walls: the profile rises most of its height within a pixel of the outline.
  if (prm.steep_fraction > 0 && phys.chance(prm.steep_fraction)) sh.p = phys.uniform(0.1, 0.22);
  if (prm.flap_probability > 0 && phys.chance(prm.flap_probability)) {
    sh.flap_h = phys.uniform(2, 4);
    sh.flap_s = phys.uniform(-0.25, 0.25) * sh.L;
    sh.flap_half = phys.uniform(0.12, 0.22) * sh.L;
    sh.flap_len = phys.uniform(6, 10);
    sh.flap_side = phys.chance(0.5) ? 1 : -1;
  }
  if (prm.fold_probability > 0 && phys.chance(prm.fold_probability)) {
    sh.fold_h = phys.uniform(3, 8);
    sh.fold_s = phys.uniform(0.1, 0.3) * sh.L;
  }
  return sh;
}

// The fillet's height raster: the shape turned by `yaw` (its long axis against the belt's),
// in a box whose meat starts at b_start.
void rasterise(Fillet& f, const Shape& sh, double yaw, double b_start, double x_center) {
  const double cy = std::cos(yaw), sy = std::sin(yaw);
  // Extent of the rotated outline (with room for the harmonics).
  const double ra = 0.5 * sh.L * 1.25, rb = 0.5 * sh.W * 1.35 * (1 + std::abs(sh.taper));
  const double ext_b = std::abs(cy) * ra + std::abs(sy) * rb;
  const double ext_x = std::abs(sy) * ra + std::abs(cy) * rb;
  f.x_center = x_center;
  f.b_center = b_start + ext_b;
  f.ix0 = int(std::floor((x_center - ext_x - kLaneX0Mm) / kRasterPitchMm));
  f.ib0 = int(std::floor(b_start / kRasterPitchMm));
  f.nx = int(std::ceil(2 * ext_x / kRasterPitchMm)) + 3;
  f.nb = int(std::ceil(2 * ext_b / kRasterPitchMm)) + 3;
  f.x_min = kLaneX0Mm + f.ix0 * kRasterPitchMm;
  f.x_max = f.x_min + (f.nx - 1) * kRasterPitchMm;
  f.b_min = f.ib0 * kRasterPitchMm;
  f.b_max = f.b_min + (f.nb - 1) * kRasterPitchMm;
  f.height.assign(size_t(f.nx) * f.nb, 0.f);
  int j_lo = f.nb, j_hi = -1;
  for (int j = 0; j < f.nb; ++j)
    for (int i = 0; i < f.nx; ++i) {
      const double dx = f.x_min + i * kRasterPitchMm - f.x_center;
      const double db = f.b_min + j * kRasterPitchMm - f.b_center;
      const double s = cy * db + sy * dx, t = -sy * db + cy * dx;
      // Raster edges stay zero so that the fillet ends inside its box.
      const float h =
          (i == 0 || j == 0 || i == f.nx - 1 || j == f.nb - 1) ? 0.f : float(sh.height(s, t));
      f.height[size_t(j) * f.nx + i] = h;
      if (h > 0) {
        j_lo = std::min(j_lo, j);
        j_hi = std::max(j_hi, j);
      }
    }
  // Slide the raster so that the meat itself (not its box) starts at b_start: the gaps
  // between fillets are then the sampled ones.
  f.b_start = b_start;
  if (j_hi >= 0) {
    f.ib0 -= j_lo;
    f.b_min = f.ib0 * kRasterPitchMm;
    f.b_center -= j_lo * kRasterPitchMm;
    f.b_max = (f.ib0 + j_hi + 1) * kRasterPitchMm;
  }
}

// Places inclusions where the meat is thick enough to hold them.
struct Placer {
  Fillet& f;
  Rng& rng;
  Rng& phys;

  // One inclusion of `size` mm and semi-axes in those fractions of it, or none where 200
  // tries found no meat thick enough. `tilt_max`: how far its long axis may rise out of the
  // belt's plane (rad).
  Inclusion* place(Inclusion::Kind kind, double size, double semi_y_frac, double semi_z_frac,
                   double dmu, double calc, double tilt_max = 0.3) {
    for (int attempt = 0; attempt < 200; ++attempt) {
      const double x = rng.uniform(f.x_min, f.x_max), b = rng.uniform(f.b_min, f.b_max);
      const double h = f.height_at(x, b);
      Inclusion in;
      in.kind = kind;
      in.semi = {0.5 * size, 0.5 * size * semi_y_frac, 0.5 * size * semi_z_frac};
      const bool steep = tilt_max > 0.3;
      const double tilt = steep ? phys.uniform(-tilt_max, tilt_max) : 0.0;
      const double zext =
          std::max({in.semi.y, in.semi.z, in.semi.x * std::abs(std::sin(tilt))}) + 0.5;
      if (h < 2 * zext + 1.0) continue;
      in.center = {x, b, rng.uniform(zext, h - zext)};
      // Lying roughly flat: the meat holds fragments along its muscle layers (needles lie
      // any way).
      in.to_local = steep
                        ? rotation_zx(rng.uniform(0, 2 * kPi), tilt).transposed()
                        : rotation_zx(rng.uniform(0, 2 * kPi), rng.uniform(-0.3, 0.3)).transposed();
      in.dmu = dmu;
      in.calcification = calc;
      in.size_mm = size;
      f.inclusions.push_back(in);
      return &f.inclusions.back();
    }
    return nullptr;
  }

  // A curved rib piece (two bent halves) or a cluster of small pieces: one fragment in the
  // truth, several ellipsoids in the meat.
  void rib_or_cluster(Inclusion::Shape shape, double size, double dmu, double calc) {
    const bool rib = shape == Inclusion::kRib;
    const double len = rib ? std::max(size, 4.0) : std::max(size, 3.0);
    const double part = rib ? 0.55 * len : 0.45 * len;
    if (!place(Inclusion::kBone, part, rib ? 0.25 : 0.6, rib ? 0.25 : 0.5, dmu, calc)) return;
    const size_t primary = f.inclusions.size() - 1;
    f.inclusions[primary].shape = shape;
    f.inclusions[primary].size_mm = len;
    const double a = phys.uniform(0, 2 * kPi);
    if (rib) f.inclusions[primary].to_local = rotation_zx(a, 0).transposed();
    const Inclusion first = f.inclusions[primary];
    const int parts = rib ? 1 : phys.integer(2, 4);
    for (int q = 0; q < parts; ++q) {
      Inclusion o = first;
      o.secondary = true;
      o.size_mm = part;
      // The rib's second half continues the first, bent by 17-34 degrees; a cluster's
      // pieces lie around the first within 40 % of its extent.
      const double ang = rib ? a : phys.uniform(0, 2 * kPi);
      const double r = rib ? 0.5 * part : phys.uniform(1, std::max(1.5, 0.4 * len));
      o.center = {first.center.x + r * std::cos(ang), first.center.y + r * std::sin(ang),
                  first.center.z};
      if (rib) {
        const double bend = phys.uniform(0.3, 0.6);
        o.center = o.center +
                   Vec3{0.5 * part * std::cos(ang + bend), 0.5 * part * std::sin(ang + bend), 0};
        o.to_local = rotation_zx(ang + bend, 0).transposed();
      } else {
        o.semi = first.semi * phys.uniform(0.6, 1.0);
      }
      if (f.height_at(o.center.x, o.center.y) > o.center.z + o.semi.z + 0.3)
        f.inclusions.push_back(o);
    }
  }

  // One bone fragment of 1-10 mm: needle, chip, rib or cluster by the plant's shares, else
  // compact.
  void bone(const FilletParams& prm) {
    constexpr double kBoneMuFull = 0.12;  // fully calcified bone, 1/mm
    static constexpr double kBins[5] = {1, 2, 3, 5, 10};
    const int bin = rng.integer(0, 3);
    const double size = rng.uniform(kBins[bin], kBins[bin + 1]);
    const double calc = rng.uniform(prm.calcification_min, prm.calcification_max);
    const double dmu = calc * (kBoneMuFull - f.mu);
    Inclusion::Shape shape = Inclusion::kCompact;
    if (prm.needle + prm.chip + prm.rib + prm.cluster > 0) {
      double pick = phys.uniform(0, 1);
      for (auto [share, kind] :
           {std::pair{prm.needle, Inclusion::kNeedle}, std::pair{prm.chip, Inclusion::kChip},
            std::pair{prm.rib, Inclusion::kRib}, std::pair{prm.cluster, Inclusion::kCluster}})
        if ((pick -= share) < 0) {
          shape = kind;
          break;
        }
    }
    if (shape == Inclusion::kNeedle) {
      // Needles and slivers: long, under a millimetre thick, at any orientation.
      const double len = std::max(size, 3.0), thick = phys.uniform(0.3, 0.8);
      if (Inclusion* in = place(Inclusion::kBone, len, thick / len, thick / len, dmu, calc, 1.2))
        in->shape = Inclusion::kNeedle;
    } else if (shape == Inclusion::kChip) {
      const double thick = phys.uniform(0.4, 0.9);
      if (Inclusion* in =
              place(Inclusion::kBone, size, phys.uniform(0.6, 0.9), thick / size, dmu, calc))
        in->shape = Inclusion::kChip;
    } else if (shape == Inclusion::kRib || shape == Inclusion::kCluster) {
      rib_or_cluster(shape, size, dmu, calc);
    } else {
      place(Inclusion::kBone, size, rng.uniform(0.35, 0.7), rng.uniform(0.3, 0.6), dmu, calc);
    }
  }
};

}  // namespace

Fillet make_fillet(Rng& rng, Rng& phys, int id, double b_start, double x_center,
                   const FilletParams& prm) {
  const Shape sh = draw_shape(rng, phys, prm);
  const double yaw = rng.uniform(-25, 25) * kPi / 180;
  Fillet f;
  f.id = id;
  rasterise(f, sh, yaw, b_start, x_center);
  f.mu = rng.uniform(0.028, 0.032);
  f.texture_amp = rng.uniform(0.005, 0.02);
  f.texture_kx = 2 * kPi / rng.uniform(15, 40);
  f.texture_kb = 2 * kPi / rng.uniform(15, 40);
  f.texture_phase = rng.uniform(0, 2 * kPi);

  Placer in{f, rng, phys};
  if (rng.chance(prm.bone_probability)) {
    const int n = rng.chance(0.3) ? 2 : 1;
    for (int k = 0; k < n; ++k) in.bone(prm);
  }
  if (rng.chance(prm.air_probability)) {
    const int n = rng.integer(1, 3);
    for (int k = 0; k < n; ++k)
      in.place(Inclusion::kAir, rng.uniform(2, 6), rng.uniform(0.6, 1.0), rng.uniform(0.5, 0.9),
               -f.mu, 0);
  }
  if (rng.chance(prm.fat_probability)) {
    const int n = rng.integer(1, 2);
    for (int k = 0; k < n; ++k)
      in.place(Inclusion::kFat, rng.uniform(10, 30), rng.uniform(0.4, 0.7), rng.uniform(0.1, 0.25),
               -0.15 * f.mu, 0);
  }
  // Cartilage and tendon: a little denser than meat, elongated; not bone.
  if (prm.cartilage_probability > 0 && phys.chance(prm.cartilage_probability)) {
    const double len = phys.uniform(6, 20);
    if (Inclusion* c = in.place(Inclusion::kCartilage, len, phys.uniform(0.1, 0.3),
                                phys.uniform(0.08, 0.2), phys.uniform(0.15, 0.35) * f.mu, 0))
      c->shape = Inclusion::kCompact;
  }
  // Rough meat draws from a stream of its own, seeded from the physics stream only when
  // asked for, so that every other plant stays draw for draw as it was.
  if (prm.meat.texture_std > 0 || prm.meat.marbling > 0) {
    Rng tex(phys.next(), 0x7e47, uint64_t(id));
    f.rough = make_meat_texture(tex, f.x_min, f.x_max, f.b_min, f.b_max, prm.meat);
  }
  return f;
}

Fillet make_debris(Rng& rng, int id, double b_start, double x_center) {
  Fillet f;
  f.id = id;
  f.debris = true;
  const double r = rng.uniform(1.5, 4), h = rng.uniform(1, 4);
  f.x_center = x_center;
  f.ix0 = int(std::floor((x_center - r - 1 - kLaneX0Mm) / kRasterPitchMm));
  f.ib0 = int(std::floor(b_start / kRasterPitchMm));
  f.nx = f.nb = int(std::ceil((2 * r + 2) / kRasterPitchMm)) + 1;
  f.x_min = kLaneX0Mm + f.ix0 * kRasterPitchMm;
  f.x_max = f.x_min + (f.nx - 1) * kRasterPitchMm;
  f.b_min = f.b_start = f.ib0 * kRasterPitchMm;
  f.b_max = f.b_min + (f.nb - 1) * kRasterPitchMm;
  f.b_center = 0.5 * (f.b_min + f.b_max);
  f.height.assign(size_t(f.nx) * f.nb, 0.f);
  for (int j = 1; j + 1 < f.nb; ++j)
    for (int i = 1; i + 1 < f.nx; ++i) {
      const double dx = f.x_min + i * kRasterPitchMm - x_center,
                   db = f.b_min + j * kRasterPitchMm - f.b_center;
      const double q = 1 - (dx * dx + db * db) / (r * r);
      if (q > 0) f.height[size_t(j) * f.nx + i] = float(h * std::sqrt(q));
    }
  return f;
}

Fillet make_test_card(int id, double b_start, const TestCard& card) {
  Fillet f;
  f.id = id;
  const double hw = 0.5 * card.width_mm;
  f.x_center = 0;
  f.ix0 = int(std::floor((-hw - 1 - kLaneX0Mm) / kRasterPitchMm));
  f.ib0 = int(std::floor(b_start / kRasterPitchMm));
  f.nx = int(std::ceil((card.width_mm + 2) / kRasterPitchMm)) + 1;
  f.nb = int(std::ceil((card.length_mm + 2) / kRasterPitchMm)) + 1;
  f.x_min = kLaneX0Mm + f.ix0 * kRasterPitchMm;
  f.x_max = f.x_min + (f.nx - 1) * kRasterPitchMm;
  f.b_min = f.b_start = f.ib0 * kRasterPitchMm;
  f.b_max = f.b_min + (f.nb - 1) * kRasterPitchMm;
  f.b_center = f.b_min + 1 + 0.5 * card.length_mm;
  f.height.assign(size_t(f.nx) * f.nb, 0.f);
  for (int j = 0; j < f.nb; ++j)
    for (int i = 0; i < f.nx; ++i) {
      // Distance inside the slab's outline; the edge rounds off as a quarter circle.
      const double dx = hw - std::abs(f.x_min + i * kRasterPitchMm);
      const double db = 0.5 * card.length_mm - std::abs(f.b_min + j * kRasterPitchMm - f.b_center);
      const double in = std::min(dx, db);
      if (in <= 0) continue;
      const double e = std::min(1.0, in / card.edge_mm);
      f.height[size_t(j) * f.nx + i] = float(card.thickness_mm * std::sqrt(1 - (1 - e) * (1 - e)));
    }
  Inclusion piece{};
  piece.kind = Inclusion::kBone;
  piece.center = {card.piece_x_mm, f.b_center, 0.5 * card.thickness_mm};
  const double r = 0.5 * card.piece_mm;
  piece.semi = {r, r, r};
  constexpr double kBoneMuFull = 0.12;  // as in the fillets
  piece.dmu = card.calcification * (kBoneMuFull - f.mu);
  piece.calcification = card.calcification;
  piece.size_mm = card.piece_mm;
  f.inclusions.push_back(piece);
  return f;
}

}  // namespace rangex::sim
