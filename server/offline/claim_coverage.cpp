#include "offline/claim_coverage.h"

#include <cmath>

namespace rangex {

namespace {
double piece_excess(const JudgedFragment& f, const ClaimMaterial& m) {
  return m.excess_per_mm > 0 ? m.excess_per_mm : m.excess_ratio * f.meat_mu;
}
}  // namespace

double equivalent_sphere_mm(const JudgedFragment& f, const ClaimMaterial& m) {
  if (f.volume_mm3 <= 0 || f.excess_mu <= 0) return -1;
  const double piece = piece_excess(f, m);
  if (!(piece > 0)) return -1;
  return std::cbrt(6 / M_PI * f.volume_mm3 * f.excess_mu / piece);
}

ClaimCoverage claim_coverage(const std::vector<JudgedFragment>& fragments,
                             const std::vector<SphereClaim>& claims, const ClaimMaterial& m) {
  ClaimCoverage c;
  for (const JudgedFragment& f : fragments) {
    if (f.shape != "compact") continue;
    const double d = equivalent_sphere_mm(f, m);
    if (d < 0 || f.meat_mm < 0) {
      ++c.unknown;
      continue;
    }
    ++c.weighed;
    const SphereClaim* claim = nullptr;
    for (const SphereClaim& k : claims)
      if (f.meat_mm >= k.band_lo_mm && f.meat_mm < k.band_hi_mm) claim = &k;
    if (!claim || d < claim->size_mm) continue;
    ++c.covered;
    c.found += f.found;
    if (f.excess_mu >= piece_excess(f, m)) ++c.dense_covered, c.dense_found += f.found;
    if (!f.found) c.missed.push_back({f, d, claim->size_mm});
  }
  return c;
}

}  // namespace rangex
