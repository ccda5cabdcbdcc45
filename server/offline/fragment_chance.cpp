#include "offline/fragment_chance.h"

#include <cmath>

#include "offline/miss_margin.h"
#include "pipeline/test_pieces.h"

namespace rangex {

namespace {

double normal_cdf(double x) {
  return 0.5 * std::erfc(-x / std::sqrt(2.0));
}

// The fillet pixel where a point at (x_mm across the belt at mid-depth, b_mm) is seen: the
// inverse of where inspection places a detection (fan beam from the source), its thickness
// taken where the first guess lands. False off the image.
bool pixel_of(const FilletImage& img, double x_mm, double b_mm, int& row, int& col) {
  row = int(std::lround((b_mm - img.y0_mm) / img.step_mm));
  const double span = img.source_z_mm - img.detector_z_mm;
  double t = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const double x_det =
        img.source_x_mm + (x_mm - img.source_x_mm) * span / (img.source_z_mm - 0.5 * t);
    col = int(std::lround((x_det - img.x0_mm) / img.pitch_mm));
    if (row < 0 || row >= img.rows || col < 0 || col >= img.cols) return false;
    const float th = img.thickness[size_t(row) * img.cols + col];
    t = std::isfinite(th) ? th : 0.0;
  }
  return true;
}

}  // namespace

FragmentChance fragment_chance(const FilletImage& img, const InspectionParams& p, double x_mm,
                               double b_mm, double tol_mm, double volume_mm3,
                               double excess_per_mm) {
  FragmentChance out;
  int row = 0, col = 0;
  if (img.xray.empty() || !(volume_mm3 > 0) || !(excess_per_mm > 0) ||
      !pixel_of(img, x_mm, b_mm, row, col))
    return out;
  const float t0 = img.thickness[size_t(row) * img.cols + col];
  if (!(t0 > 0)) return out;
  InspectionParams q = p;
  q.band_extremes = false;
  const FilletResult before = inspect_fillet(img, q, true);
  if (before.round_stat.size() != img.size()) return out;  // not inspected
  FilletImage with = img;
  TestPiece piece;
  piece.shape = TestPiece::kSphere;
  piece.size_mm = std::cbrt(6 * volume_mm3 / M_PI);
  piece.row = row, piece.col = col;
  piece.height_mm = 0.5 * t0;
  TestPieceMaterial material;
  material.excess_per_mm = excess_per_mm;
  inject_test_piece(with, piece, 0, material);
  const FilletResult after = inspect_fillet(with, q, true);
  if (after.round_stat.size() != img.size()) return out;
  const LearnedDetection& L = p.learned;
  const int gr = int(std::ceil(tol_mm / img.step_mm)), gc = int(std::ceil(tol_mm / img.pitch_mm));
  for (int s : {int(kStatRound), int(kStatNeedle)}) {
    const std::vector<float>& a = s == kStatRound ? before.round_stat : before.needle_stat;
    const std::vector<float>& b = s == kStatRound ? after.round_stat : after.needle_stat;
    double best = -1, seen = -1e30;
    size_t at = 0;
    for (int r = std::max(0, row - gr); r <= std::min(img.rows - 1, row + gr); ++r)
      for (int c = std::max(0, col - gc); c <= std::min(img.cols - 1, col + gc); ++c) {
        const size_t i = size_t(r) * img.cols + c;
        if (!std::isfinite(a[i]) || !std::isfinite(b[i])) continue;
        if (b[i] - a[i] > best) best = b[i] - a[i], at = i;
        seen = std::max(seen, double(a[i]));
      }
    if (best < 0) continue;
    const double th = L.active() ? L.threshold(s, img.thickness[at]) : p.z_threshold;
    const double chance = normal_cdf(best - th);
    if (chance > out.chance) out = {s, best, th, chance, seen};
  }
  return out;
}

void measure_fragment_chances(DetectionEval& e, int lane,
                              const std::vector<InspectedFillet>& fillets,
                              const InspectionParams& p) {
  for (JudgedFragment& j : e.judged) {
    if (j.lane != lane || j.size_mm < 2 || j.calcification < kCalcified) continue;
    if (!(j.volume_mm3 > 0) || !(j.excess_mu > 0)) continue;
    const InspectedFillet* f = fillet_holding(fillets, j.x_mm, j.b_mm);
    if (!f) continue;
    const FragmentChance c =
        fragment_chance(f->image, p, j.x_mm, j.b_mm, j.tol_mm, j.volume_mm3, j.excess_mu);
    if (c.chance < 0) continue;
    j.chance = c;
    for (MissedFragment& m : e.missed)
      if (m.lane == lane && m.x_mm == j.x_mm && m.b_mm == j.b_mm) m.chance = c;
  }
}

double expected_recall(const DetectionEval& e, int& n) {
  double sum = 0;
  n = 0;
  for (const JudgedFragment& j : e.judged)
    if (j.size_mm >= 2 && j.calcification >= kCalcified && j.chance.chance >= 0)
      sum += j.chance.chance, ++n;
  return n ? sum / n : -1;
}

}  // namespace rangex
