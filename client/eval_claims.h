// eval-matrix: the learned report's sphere claims held against the variant's own fragments
// (offline/claim_coverage.h), the plant's and the bone run's pooled. The test pieces say
// what the claims are worth on pieces injected into clean fillets; this says it on the
// compact bone the simulator put into the plant.
#pragma once
#include <string>
#include <vector>

#include "eval_bone_run.h"
#include "offline/claim_coverage.h"

namespace rangex::cli {

struct ReportClaims {
  std::vector<SphereClaim> spheres;
  ClaimMaterial material;
};

// The sphere claims and the pieces' material of lane `lane` in a learning report
// (learn.json); a report without the material names it.
ReportClaims report_claims(const std::string& learn_json, int lane);

// The plant's fragments (seed `plant_seed`) and each bone part's, pooled; each covered miss
// with the seed of the recording it lies in.
struct FragmentClaims {
  ClaimCoverage pooled;
  std::vector<long> missed_seed;
};
FragmentClaims claims_on_fragments(const ReportClaims& rc, const DetectionEval& plant,
                                   long plant_seed, const std::vector<BonePart>& bones);

// "rough_meat: 87/89 found of the compact fragments its sphere claims cover ..." and each
// covered miss.
std::string claims_text(const std::string& name, const FragmentClaims& c);
std::string claims_json(const FragmentClaims& c);

}  // namespace rangex::cli
