// What lies on one lane's belt: a row of fillets with gaps, in object coordinates
// (x across, b along the belt; the laser plane sees b = belt_offset - y_laser).
#pragma once
#include <cstdint>
#include <optional>
#include <vector>

#include "sim/fillet.h"

namespace rangex::sim {

struct SceneParams {
  int fillets = 5;
  double lead_in_mm = 40;              // empty belt before the first fillet
  double close_gap_probability = 0.2;  // fillets almost touching
  double scatter_spread = 0;           // per fillet, the tail scales by exp(spread N(0,1))
  double debris_probability = 0;       // a small bit of meat in a gap between fillets
  double fat_share_min = 0.02, fat_share_max = 0.10;  // each fillet's fat share (dual energy)
  FilletParams fillet;
  // Verification test cards instead of fillets (card.piece_x_mm: where their piece lies).
  std::optional<TestCard> test_cards;
};

class LaneScene {
 public:
  LaneScene(uint64_t seed, int lane, const SceneParams& p);

  float height(double x, double b) const;  // highest fillet surface at (x, b), 0 on the belt
  // Heights at x = kLaneX0Mm + k * kRasterPitchMm, k < n, on the slice b.
  void slice(double b, float* out, int n) const;
  double end_b() const { return end_b_; }
  const std::vector<Fillet>& fillets() const { return fillets_; }
  // Highest fillet surface among the fillets that overlap [b_lo, b_hi] (0 if none).
  float max_height(double b_lo, double b_hi) const;
  // Whether height is 0 everywhere in [x_lo, x_hi] x [b_lo, b_hi]: no fillet's raster reaches it.
  bool bare(double x_lo, double x_hi, double b_lo, double b_hi) const;
  bool is_meat(const Vec3& p) const { return p.z > 0.05; }  // above the belt: a fillet
  // How strongly the meat at world point p (belt offset s) scatters, against the plant's
  // usual (fat, skin side up or down): the fillet's own factor.
  double scatter_scale(const Vec3& p, double s) const;

 private:
  std::vector<Fillet> fillets_;  // ordered by b
  std::vector<double> box_end_;  // running maximum of the fillets' raster ends, for search
  std::vector<float> peak_;      // each fillet's highest point
  double end_b_ = 0;
  template <typename F>
  void for_fillets(double b_lo, double b_hi, F&& f) const;
};

}  // namespace rangex::sim
