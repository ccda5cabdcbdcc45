#include "pipeline/sensitivity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>

#include "pipeline/binomial_tail.h"
#include "pipeline/detection_curve.h"
#include "pipeline/inspection.h"
#include "pipeline/inspection_steps.h"

namespace rangex {

const char* piece_shape_name(int shape) {
  return shape == TestPiece::kNeedle ? "needle" : "sphere";
}

double SensitivityFillet::meat_mu(double t) const {
  return std::clamp(-(beta1 + 2 * beta2 * t), 0.005, 0.3);
}

namespace {

// Pixels at least `margin` px inside the mask (a square neighbourhood), with a thickness.
std::vector<size_t> inside_pixels(const FilletImage& img, int margin_r, int margin_c) {
  std::vector<size_t> out;
  for (int r = margin_r; r < img.rows - margin_r; ++r)
    for (int c = margin_c; c < img.cols - margin_c; ++c) {
      const size_t i = size_t(r) * img.cols + c;
      if (!img.mask[i] || !std::isfinite(img.thickness[i])) continue;
      bool inside = true;
      for (int dr : {-margin_r, margin_r})
        for (int dc : {-margin_c, 0, margin_c})
          inside = inside && img.mask[size_t(r + dr) * img.cols + c + dc];
      for (int dc : {-margin_c, margin_c})
        inside = inside && img.mask[size_t(r) * img.cols + c + dc];
      if (inside) out.push_back(i);
    }
  return out;
}

}  // namespace

void state_claims(SensitivityResult& res, const SensitivityOptions& opt) {
  const int bands = int(res.band_edges_mm.size()) - 1;
  for (int shape = 0; shape < 2; ++shape) {
    auto seen = [&](int band) {
      return std::any_of(res.cells.begin(), res.cells.end(), [&](const auto& c) {
        return c.shape == shape && c.band == band && c.injected >= opt.min_pieces;
      });
    };
    auto claims = [&](int band, double size) {
      return std::any_of(res.claims.begin(), res.claims.end(), [&](const auto& c) {
        return c.shape == shape && c.band == band && c.size_mm <= size;
      });
    };
    // The bands from `from` up (unseen ones skipped) in which `size` is claimed.
    auto run = [&](int from, double size, int& last) {
      int n = 0;
      last = -1;
      for (int band = from; band < bands; ++band) {
        if (!seen(band)) continue;  // no meat that thick among the fillets: no claim either way
        if (!claims(band, size)) break;
        ++n, last = band;
      }
      return n;
    };
    int thinnest = 0;
    while (thinnest < bands && !seen(thinnest)) ++thinnest;
    int first = thinnest;
    while (first < bands && !(seen(first) && claims(first, HUGE_VAL))) ++first;
    StatedClaim best{shape, 0, first, -1, 0, {}};
    for (double size : opt.sizes_mm)
      if (first < bands && run(first, size, best.last_band) > 0) {
        best.size_mm = size;
        break;  // the smallest size that holds from there up
      }
    if (best.last_band < 0) continue;
    const double hi = res.band_edges_mm[size_t(best.last_band) + 1];
    const bool open = best.last_band == bands - 1 && hi > 100;
    best.up_to_mm = hi;
    char b[200];
    char upper[80];
    std::snprintf(upper, sizeof upper, open ? "at any thickness seen, up to %.0f" : "up to %.0f",
                  open ? res.band_edges_mm[size_t(bands) - 1] + 5 : hi);
    if (best.first_band == thinnest)
      std::snprintf(b, sizeof b, "%.1f mm calcified %s at %.0f %% %s mm of meat", best.size_mm,
                    piece_shape_name(shape), 100 * opt.rate, upper);
    else
      std::snprintf(b, sizeof b, "%.1f mm calcified %s at %.0f %% from %.0f mm of meat %s mm",
                    best.size_mm, piece_shape_name(shape), 100 * opt.rate,
                    res.band_edges_mm[size_t(best.first_band)], upper);
    best.text = b;
    res.summary.push_back(b);
    res.stated.push_back(best);
  }
  if (res.summary.empty()) {
    char b[160];
    std::snprintf(b, sizeof b,
                  "no claim: no size found at %.0f %% in any thickness band (at least %d test "
                  "pieces a band; more fillets give more)",
                  100 * opt.rate, opt.min_pieces);
    res.summary.push_back(b);
  }
}

SensitivityResult measure_sensitivity(const std::vector<SensitivityFillet>& fillets,
                                      const InspectionParams& p, const SensitivityOptions& opt,
                                      const std::function<void(int, int)>& progress) {
  return measure_sensitivity_each(fillets, p, {p.learned}, opt, progress).front();
}

std::vector<SensitivityResult> measure_sensitivity_each(
    const std::vector<SensitivityFillet>& fillets, const InspectionParams& p,
    const std::vector<LearnedDetection>& learned, const SensitivityOptions& opt,
    const std::function<void(int, int)>& progress) {
  const size_t sets = learned.size();
  std::vector<SensitivityResult> out(sets);
  for (size_t k = 0; k < sets; ++k)
    out[k].band_edges_mm = !opt.band_edges_mm.empty() ? opt.band_edges_mm
                           : learned[k].active()      ? learned[k].band_edges_mm
                                                      : default_band_edges_mm();
  std::vector<std::map<std::tuple<int, double, int>, SensitivityCell>> cells(sets);
  std::mt19937_64 rng(opt.seed);
  const int total = int(fillets.size() * 2 * opt.sizes_mm.size());
  int done = 0;
  for (const SensitivityFillet& f : fillets) {
    const FilletImage& base = *f.image;
    const int mr = std::max(1, int(std::ceil(opt.edge_margin_mm / base.step_mm)));
    const int mc = std::max(1, int(std::ceil(opt.edge_margin_mm / base.pitch_mm)));
    const std::vector<size_t> inside = inside_pixels(base, mr, mc);
    for (int shape = 0; shape < 2; ++shape)
      for (double size : opt.sizes_mm) {
        if (progress) progress(++done, total);
        // A sphere needs the meat to hold it; a needle lies flat.
        const double need = shape == TestPiece::kSphere ? size + 1.0 : 2.0;
        std::vector<size_t> cand;
        for (size_t i : inside)
          if (base.thickness[i] >= need) cand.push_back(i);
        std::shuffle(cand.begin(), cand.end(), rng);
        std::vector<TestPiece> placed;
        std::uniform_real_distribution<double> angle(0, M_PI);
        for (size_t i : cand) {
          if (int(placed.size()) >= opt.pieces_per_fillet) break;
          const int r = int(i / size_t(base.cols)), c = int(i % size_t(base.cols));
          bool far = true;
          for (const TestPiece& q : placed)
            far = far && std::hypot((r - q.row) * base.step_mm, (c - q.col) * base.pitch_mm) >=
                             opt.spacing_mm;
          if (!far) continue;
          TestPiece piece;
          piece.shape = TestPiece::Shape(shape);
          piece.size_mm = size;
          piece.row = r, piece.col = c;
          const double t = base.thickness[i];
          const double rad =
              shape == TestPiece::kSphere ? 0.5 * size : 0.5 * opt.material.needle_diameter_mm;
          const double depth = opt.depths[placed.size() % opt.depths.size()];
          piece.height_mm = std::clamp(depth * t, rad, std::max(rad, t - rad));
          piece.angle_rad = angle(rng);
          placed.push_back(piece);
        }
        if (placed.empty()) continue;
        FilletImage img = base;
        const bool dual = base.has_dual_energy && base.xray_high.size() == base.size();
        for (const TestPiece& q : placed) {
          const size_t at = size_t(q.row) * base.cols + q.col;
          if (!dual) {
            inject_test_piece(img, q, f.meat_mu(base.thickness[at]), opt.material);
            continue;
          }
          // Dual energy: the piece is bone calcified so that the low line sees the material's
          // excess over the meat; the high line sees that bone's own.
          double lean[2], bone[2];
          if (!dual_energy_slopes(base, at, lean, bone)) continue;
          const double calcified = opt.material.excess(lean[0]) / (bone[0] - lean[0]);
          inject_test_piece(img, q, lean[0], opt.material, calcified * (bone[1] - lean[1]));
        }
        const std::vector<FilletResult> rs = inspect_fillet_each(img, p, learned);
        for (size_t k = 0; k < sets; ++k) {
          ++out[k].inspections;
          for (const TestPiece& q : placed) {
            const double t = base.thickness[size_t(q.row) * base.cols + q.col];
            const int band = band_index(out[k].band_edges_mm, t);
            SensitivityCell& cell = cells[k][{shape, size, band}];
            cell.shape = shape, cell.size_mm = size, cell.band = band;
            ++cell.injected;
            // Found: a fragment's box, grown by the evaluation's distance, holds its centre.
            const double tol = std::max(2.0, 0.5 * size + 1);
            const int gr = int(std::ceil(tol / base.step_mm)),
                      gc = int(std::ceil(tol / base.pitch_mm));
            for (const Blob& b : rs[k].fragments)
              if (q.row >= b.row0 - gr && q.row <= b.row1 + gr && q.col >= b.col0 - gc &&
                  q.col <= b.col1 + gc) {
                ++cell.found;
                break;
              }
          }
        }
      }
  }
  for (size_t k = 0; k < sets; ++k) {
    SensitivityResult& res = out[k];
    for (auto& [key, c] : cells[k]) res.cells.push_back(c);
    res.claims = claim_sizes(res.cells, res.band_edges_mm, opt);
    res.rate = opt.rate, res.claim_confidence = opt.claim_confidence;
    res.material = opt.material;
    state_claims(res, opt);
  }
  return out;
}

std::vector<SensitivityClaim> claim_sizes(const std::vector<SensitivityCell>& cells,
                                          const std::vector<double>& band_edges_mm,
                                          const SensitivityOptions& opt) {
  std::vector<SensitivityClaim> out;
  const int bands = int(band_edges_mm.size()) - 1;
  for (int shape = 0; shape < 2; ++shape)
    for (int band = 0; band < bands; ++band) {
      std::vector<HitMiss> data;
      for (const SensitivityCell& c : cells)
        if (c.shape == shape && c.band == band) data.push_back({c.size_mm, c.injected, c.found});
      const DetectionCurve curve = fit_detection_curve(data);
      auto cell = [&](double size) {
        return std::find_if(data.begin(), data.end(),
                            [&](const HitMiss& d) { return std::abs(d.size_mm - size) < 1e-9; });
      };
      double claim = NAN, lower = NAN;
      for (auto it = opt.sizes_mm.rbegin(); it != opt.sizes_mm.rend(); ++it) {
        const auto c = cell(*it);
        if (c == data.end() || c->injected < opt.min_pieces ||
            double(c->found) < opt.rate * c->injected)
          break;
        const double bound = detection_lower_bound(data, curve, *it, opt.claim_confidence);
        if (!(bound >= opt.rate)) break;
        claim = *it, lower = bound;
      }
      if (std::isfinite(claim))
        out.push_back({shape, band, band_edges_mm[size_t(band)], band_edges_mm[size_t(band) + 1],
                       claim, lower});
    }
  return out;
}

namespace {

// The pieces of one shape and size in bands first..last of `measured`, pooled; `held` when
// at least `rate` of them were found.
template <class Claim>
Checked<Claim> pooled(const Claim& c, int first, int last, const SensitivityResult& measured,
                      double rate) {
  Checked<Claim> k{c};
  const int shape = c.shape;
  const double size_mm = c.size_mm;
  for (const SensitivityCell& m : measured.cells)
    if (m.shape == shape && std::abs(m.size_mm - size_mm) < 1e-9 && m.band >= first &&
        m.band <= last)
      k.injected += m.injected, k.found += m.found;
  k.held = k.injected > 0 && double(k.found) >= rate * k.injected;
  k.rate = rate;
  k.p_at_rate = binomial_at_most(k.found, k.injected, rate);
  k.contradicted = k.injected > 0 && k.p_at_rate < kClaimContradiction;
  return k;
}

template <class Claim>
std::string outcome_text(const Checked<Claim>& k) {
  char b[256];
  const int n =
      std::snprintf(b, sizeof b, "%d of %d found (%.1f %%): %s", k.found, k.injected,
                    k.injected ? 100.0 * k.found / k.injected : 0.0, k.held ? "held" : "NOT held");
  if (!k.held && k.injected > 0)
    std::snprintf(b + n, sizeof b - size_t(n),
                  "; at a true %.0f %% this few or fewer in %.2g %% of checks: %s", 100 * k.rate,
                  100 * k.p_at_rate,
                  k.contradicted ? "evidence against the claim" : "no evidence against it");
  return b;
}

}  // namespace

std::string claim_check_text(const ClaimCheck& k) {
  char b[128];
  if (k.claim.band_hi_mm >= 1000)  // the last band is open
    std::snprintf(b, sizeof b, "%s %.1f mm over %g mm of meat: ", piece_shape_name(k.claim.shape),
                  k.claim.size_mm, k.claim.band_lo_mm);
  else
    std::snprintf(b, sizeof b, "%s %.1f mm at %g-%g mm of meat: ", piece_shape_name(k.claim.shape),
                  k.claim.size_mm, k.claim.band_lo_mm, k.claim.band_hi_mm);
  return b + outcome_text(k);
}

std::string claim_check_text(const StatedCheck& k) {
  return outcome_text(k);
}

std::vector<ClaimCheck> check_claims(const std::vector<SensitivityClaim>& claims,
                                     const SensitivityResult& measured, double rate) {
  std::vector<ClaimCheck> out;
  for (const SensitivityClaim& c : claims) out.push_back(pooled(c, c.band, c.band, measured, rate));
  return out;
}

std::vector<StatedCheck> check_stated_claims(const std::vector<StatedClaim>& stated,
                                             const SensitivityResult& measured, double rate) {
  std::vector<StatedCheck> out;
  for (const StatedClaim& c : stated)
    out.push_back(pooled(c, c.first_band, c.last_band, measured, rate));
  return out;
}

}  // namespace rangex
