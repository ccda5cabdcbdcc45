#include "sim/lane_scene.h"

#include <algorithm>
#include <cmath>

namespace rangex::sim {

LaneScene::LaneScene(uint64_t seed, int lane, const SceneParams& p) {
  Rng rng(seed, 0x5ce9e, uint64_t(lane));
  double b = p.lead_in_mm;
  for (int i = 0; i < p.fillets; ++i) {
    const double x = rng.uniform(-25, 25);
    Rng physics(seed, 0xf11e7, uint64_t(lane), uint64_t(i));
    fillets_.push_back(p.test_cards ? make_test_card(i, b, *p.test_cards)
                                    : make_fillet(rng, physics, i, b, x, p.fillet));
    const Fillet& f = fillets_.back();
    end_b_ = f.b_max;
    float peak = 0;
    for (float h : f.height) peak = std::max(peak, h);
    peak_.push_back(peak);
    const double end = (f.ib0 + f.nb - 1) * kRasterPitchMm;
    box_end_.push_back(box_end_.empty() ? end : std::max(box_end_.back(), end));
    const double gap =
        rng.chance(p.close_gap_probability) ? rng.uniform(2, 10) : rng.uniform(20, 80);
    b = f.b_max + gap;
  }
  // A plant's own physics draws from streams of its own, so the nominal scene is unchanged.
  for (Fillet& f : fillets_) {
    if (p.scatter_spread > 0) {
      Rng r(seed, 0x5ca7, uint64_t(lane), uint64_t(f.id));
      f.scatter_scale = std::exp(p.scatter_spread * r.normal());
    }
    Rng r(seed, 0xfa75, uint64_t(lane), uint64_t(f.id));
    f.fat_share = r.uniform(p.fat_share_min, p.fat_share_max);
  }
  if (p.debris_probability > 0) {
    Rng r(seed, 0xdeb, uint64_t(lane));
    const size_t n = fillets_.size();
    for (size_t i = 0; i + 1 < n; ++i) {
      const double lo = fillets_[i].b_max + 4, hi = fillets_[i + 1].b_start - 4;
      if (hi - lo < 6 || !r.chance(p.debris_probability)) continue;
      fillets_.push_back(make_debris(r, int(n + i), r.uniform(lo, hi - 5), r.uniform(-60, 60)));
    }
    // Keep the order by b and the search structures.
    std::sort(fillets_.begin(), fillets_.end(),
              [](const Fillet& a, const Fillet& b) { return a.b_min < b.b_min; });
    peak_.clear();
    box_end_.clear();
    for (const Fillet& f : fillets_) {
      float peak = 0;
      for (float h : f.height) peak = std::max(peak, h);
      peak_.push_back(peak);
      const double end = (f.ib0 + f.nb - 1) * kRasterPitchMm;
      box_end_.push_back(box_end_.empty() ? end : std::max(box_end_.back(), end));
    }
  }
}

double LaneScene::scatter_scale(const Vec3& p, double s) const {
  const double b = s - p.y;
  double k = 1;
  for_fillets(b, b, [&](const Fillet& f) {
    if (f.height_at(p.x, b) > 0) k = f.scatter_scale;
  });
  return k;
}

template <typename F>
void LaneScene::for_fillets(double b_lo, double b_hi, F&& f) const {
  // Skip the fillets that end before b_lo (box_end_ is non-decreasing).
  const size_t first =
      size_t(std::lower_bound(box_end_.begin(), box_end_.end(), b_lo) - box_end_.begin());
  for (size_t i = first; i < fillets_.size(); ++i) {
    const Fillet& fl = fillets_[i];
    const double box_hi = (fl.ib0 + fl.nb - 1) * kRasterPitchMm;
    if (fl.b_min > b_hi) break;  // ordered by b: nothing further can overlap
    if (box_hi >= b_lo) f(fl);
  }
}

float LaneScene::height(double x, double b) const {
  float h = 0;
  for_fillets(b, b, [&](const Fillet& f) { h = std::max(h, f.height_at(x, b)); });
  return h;
}

void LaneScene::slice(double b, float* out, int n) const {
  std::fill(out, out + n, 0.f);
  for_fillets(b, b, [&](const Fillet& f) {
    const int k0 = std::max(0, f.ix0), k1 = std::min(n - 1, f.ix0 + f.nx - 1);
    for (int k = k0; k <= k1; ++k)
      out[k] = std::max(out[k], f.height_at(kLaneX0Mm + k * kRasterPitchMm, b));
  });
}

bool LaneScene::bare(double x_lo, double x_hi, double b_lo, double b_hi) const {
  // height_at is 0 outside a fillet's raster nodes; 1 mm to spare for its rounding.
  constexpr double kSpare = 1;
  bool bare = true;
  for_fillets(b_lo - kSpare, b_hi + kSpare, [&](const Fillet& f) {
    const double x0 = kLaneX0Mm + f.ix0 * kRasterPitchMm, x1 = x0 + f.nx * kRasterPitchMm,
                 b0 = f.ib0 * kRasterPitchMm, b1 = b0 + f.nb * kRasterPitchMm;
    if (x_hi >= x0 - kSpare && x_lo <= x1 + kSpare && b_hi >= b0 - kSpare && b_lo <= b1 + kSpare)
      bare = false;
  });
  return bare;
}

float LaneScene::max_height(double b_lo, double b_hi) const {
  float h = 0;
  for_fillets(b_lo, b_hi,
              [&](const Fillet& f) { h = std::max(h, peak_[size_t(&f - fillets_.data())]); });
  return h;
}

}  // namespace rangex::sim
