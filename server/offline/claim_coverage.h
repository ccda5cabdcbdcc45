// Whether a learned report's sensitivity claims hold on the plant's own fragments, not only
// on the test pieces injected to make them. A claim says "a calcified sphere of d mm at 95 %
// in this band of meat"; a compact bone fragment that lies in the band and holds at least
// that sphere's bone (its volume times its attenuation over the meat, against the test
// piece's) is one the claim covers, and should be found at the claimed rate. Fragments of
// other shapes spread their bone differently and are left out; so are those the claims say
// nothing of, where the development plants' missed calcified fragments >= 2 mm lie
// (docs/figures.md).
#pragma once
#include <vector>

#include "offline/detection_eval.h"

namespace rangex {

struct SphereClaim {
  double band_lo_mm = 0, band_hi_mm = 0;  // meat along the ray
  double size_mm = 0;                     // the sphere claimed there
};

// The test pieces' material as the learning injected them (pipeline/test_pieces.h): excess
// attenuation `excess_per_mm` if > 0, else `excess_ratio` times the meat's own.
struct ClaimMaterial {
  double excess_ratio = 2, excess_per_mm = 0;
};

// The diameter of the test sphere holding as much excess attenuation as the fragment
// (volume x its excess over the meat, against the piece's excess in the same meat); -1 where
// the truth lacks what it takes.
double equivalent_sphere_mm(const JudgedFragment& f, const ClaimMaterial& m);

// A covered fragment not found, with its equivalent sphere and the claim that covered it.
struct CoveredMiss {
  JudgedFragment fragment;
  double sphere_mm = 0, claim_mm = 0;
};

struct ClaimCoverage {
  int found = 0, covered = 0;       // covered: compact, in a claimed band, at least the size
  std::vector<CoveredMiss> missed;  // covered ones not found
  // Of the covered, those at least as dense as the test piece (its excess per mm or more): a
  // claim's sphere has the piece's material, so a larger, thinner fragment holding as much
  // bone stands out less than the sphere does.
  int dense_found = 0, dense_covered = 0;
  int weighed = 0;  // compact bone fragments weighed
  int unknown = 0;  // compact bone fragments the truth cannot weigh
};

ClaimCoverage claim_coverage(const std::vector<JudgedFragment>& fragments,
                             const std::vector<SphereClaim>& claims, const ClaimMaterial& m);

}  // namespace rangex
