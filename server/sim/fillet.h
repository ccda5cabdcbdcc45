// A simulated chicken-breast fillet: outline, thickness field (a height raster on the belt)
// and the inclusions the X-ray sees (bone fragments, air pockets, fat).
#pragma once
#include <cstdint>
#include <vector>

#include "core/vec.h"
#include "sim/meat_texture.h"
#include "sim/rng.h"

namespace rangex::sim {

// Object coordinates: x across the belt, b along the belt (mm, grows against the travel
// direction so that the laser sees b = line * step), z up from the belt.
constexpr double kRasterPitchMm = 0.2;
constexpr double kLaneX0Mm = -110.0;  // raster nodes sit at kLaneX0Mm + k * pitch

struct Inclusion {
  enum Kind { kBone, kAir, kFat, kCartilage } kind;
  enum Shape { kCompact, kNeedle, kChip, kRib, kCluster } shape = kCompact;
  bool secondary = false;    // another part of the fragment before it (rib, cluster)
  Vec3 center;               // (x, b, z)
  Vec3 semi;                 // semi-axes in the inclusion's own frame, mm
  Mat3 to_local;             // object -> inclusion frame rotation
  double dmu;                // attenuation difference to meat, 1/mm
  double calcification = 0;  // bones: 0..1
  double size_mm = 0;        // longest dimension

  // Length of the chord of a line p(t) = o + t d (|d| = 1) through the ellipsoid.
  double chord(const Vec3& o, const Vec3& d) const;
};

struct Fillet {
  int id = 0;
  double x_center = 0, b_center = 0;
  double b_min = 0, b_max = 0, x_min = 0, x_max = 0;  // raster extent (b_max: end of the meat)
  double b_start = 0;                                 // where the meat begins
  int nx = 0, nb = 0;
  int ix0 = 0, ib0 = 0;       // raster origin in global node indices
  std::vector<float> height;  // nb * nx, mm
  std::vector<Inclusion> inclusions;
  double mu = 0.03;          // meat attenuation, 1/mm
  double scatter_scale = 1;  // this fillet's scattering against the plant's usual
  double fat_share = 0.05;   // fat's share of the meat (dual energy renders lean and fat)
  bool debris = false;
  double texture_amp = 0, texture_kx = 0, texture_kb = 0, texture_phase = 0;
  MeatTexture rough;  // a plant's rough meat (empty in the nominal simulator)

  // Height at an object point (bilinear on the raster), 0 outside.
  float height_at(double x, double b) const;
  double mu_at(double x, double b) const;
};

struct FilletParams {
  double bone_probability = 0.5;
  double air_probability = 0.2;
  double fat_probability = 0.4;
  // A plant's own physics (sim/plant_physics.h), drawn from a stream of its own so that
  // the defaults give the nominal fillets draw for draw.
  double calcification_min = 0.3, calcification_max = 1.0;
  double needle = 0, chip = 0, rib = 0, cluster = 0;  // shares of the fragment shapes
  double cartilage_probability = 0;
  double steep_fraction = 0, flap_probability = 0, fold_probability = 0;
  MeatTextureParams meat;
};

// Builds a fillet whose leading edge (smallest b) is at b_start; x_center is its centre
// across the belt. Returns with b_max set, so the next fillet can follow. `physics` draws
// what only a plant's own physics asks for.
Fillet make_fillet(Rng& rng, Rng& physics, int id, double b_start, double x_center,
                   const FilletParams& p);

// A small bit of meat (debris) lying on the belt.
Fillet make_debris(Rng& rng, int id, double b_start, double x_center);

// A verification test card: a slab of meat-equivalent plastic with one test piece (a sphere
// of bone, calcified as given) at a known place across the belt.
struct TestCard {
  double width_mm = 60, length_mm = 120, thickness_mm = 15;
  double edge_mm = 3;  // the slab's edges round off over this
  double piece_mm = 2, piece_x_mm = 0, calcification = 1.0;
};
// Centred at x = 0 across the belt, its leading edge at b_start.
Fillet make_test_card(int id, double b_start, const TestCard& card);

}  // namespace rangex::sim
