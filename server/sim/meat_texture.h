// Meat as rough as real meat: the attenuation of a fillet varies with its
// texture (muscle fibres, connective tissue: a random field correlated over 1-5 mm, two
// scales mixed) and its fat marbling (streaks along the muscle where the meat attenuates
// less). Both are a per-fillet field of relative attenuation over the belt plane. The
// dissertation measured a residual of 1.5 % of 12 bits on real fillets; the nominal
// simulator leaves 0.46 %.
#pragma once
#include <vector>

#include "sim/rng.h"

namespace rangex::sim {

struct MeatTexture {
  double x0 = 0, b0 = 0, pitch = 0.4;
  int nx = 0, nb = 0;
  std::vector<float> factor;  // relative attenuation - 1, per node
  // The marbling alone: fat's share of the meat per node (0..1; empty without marbling), and
  // how much less fat attenuates (the single-energy renderer's contrast).
  std::vector<float> fat;
  double contrast = 0;
  bool empty() const { return factor.empty(); }
  double at(double x, double b) const;      // bilinear; 0 outside
  double fat_at(double x, double b) const;  // bilinear; 0 outside or without marbling
  // The texture alone (the marbling's attenuation taken out): relative density - 1.
  double density_at(double x, double b) const;
};

struct MeatTextureParams {
  double texture_std = 0;           // relative std of the meat's attenuation
  double marbling = 0;              // area fraction of fat streaks
  double marbling_contrast = 0.15;  // fat attenuates this much less than lean
};

MeatTexture make_meat_texture(Rng& rng, double x_min, double x_max, double b_min, double b_max,
                              const MeatTextureParams& p);

}  // namespace rangex::sim
