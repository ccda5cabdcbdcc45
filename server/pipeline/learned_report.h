// The report of a product learning (rangexctl learn, ControlService.LearnProduct) as JSON,
// and the gate it sets for activation: learned settings whose report failed (too few
// fillets, a learning run that held bone) are not activated unless forced.
#pragma once
#include <string>
#include <vector>

#include "pipeline/lane_learning.h"
#include "pipeline/product_learning.h"
#include "pipeline/sensitivity.h"

namespace rangex {

// One lane's report: the learning (thresholds, models, flagged fillets, QQ), the
// sensitivity it buys and, when asked, what other false-reject targets would buy.
std::string learned_report_json(int lane, const ProductLearning& learning,
                                const SensitivityResult& sensitivity,
                                const std::vector<TradeoffPoint>& tradeoff = {});
// The sensitivity claims checked on held-out fillets: per band, and the report's sentences.
std::string claim_checks_json(const std::string& recording, int fillets,
                              const std::vector<ClaimCheck>& checks,
                              const std::vector<StatedCheck>& stated,
                              const std::vector<SensitivityCell>& cells);

struct LearnedReportStatus {
  bool present = false, passed = false;
  std::string why;  // what is missing or failed; empty when passed
  // The lane's fillets the learning named as holding something like bone, and those kept in
  // because they were checked clean.
  std::vector<int64_t> flagged, kept;
};
// `report`: a lane's report, or rangexctl learn's {"lanes": [...]} (the lane's entry).
LearnedReportStatus check_learned_report(const std::string& report, int lane);

}  // namespace rangex
