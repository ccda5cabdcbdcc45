// What a lane learns from its own clean product, the same for rangexctl learn (a recording
// or a simulated plant) and a live learning run in the server (ControlService.LearnProduct):
// the learning fillets (each inspected fillet's extremes and a copy of its image for the
// test pieces), the extreme-value thresholds fitted to them (product_learning.h) and the
// sensitivity those thresholds buy on the same fillets (sensitivity.h).
#pragma once
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/inspection.h"
#include "pipeline/lane_processor.h"
#include "pipeline/product_learning.h"
#include "pipeline/sensitivity.h"

namespace rangex {

struct LearningSet {
  std::vector<LearningFillet> fillets;
  std::vector<FilletImage> images;              // of `fillets`, in the same order
  std::vector<std::pair<double, double>> fits;  // their fits' b1, b2 (the meat's attenuation)
  int not_inspected = 0;                        // fillets left out

  // A fillet that was not inspected (or not fitted) says nothing about the product's texture.
  static bool teaches(const FilletResult& r);
  // The fillet joins the set when it teaches; otherwise it is counted as left out.
  void add(const FilletResult& r, FilletImage image);
  size_t size() const { return fillets.size(); }
  std::vector<SensitivityFillet> sensitivity_fillets() const;
};

// What another false-reject target would buy on the same product: the thresholds the same
// fillets' models give for `target_frr` (the same confidence, kernels and bands), and the
// sensitivity measured with them on the same fillets and test pieces. A plant chooses its
// `false_reject_target` from these: a lower rate costs sensitivity, a higher one buys it.
struct TradeoffPoint {
  double target_frr = 0;
  double implied_frr = 0;  // at its thresholds, under the fitted models
  LearnedDetection learned;
  SensitivityResult sensitivity;
};

struct LaneLearning {
  ProductLearning learning;       // its thresholds carry `version` and `learned_on`
  InspectionParams inspection;    // the lane's inspection with those thresholds
  SensitivityResult sensitivity;  // what they buy on the learning fillets
  // The learning fillets' extremes the thresholds were fitted to (with the lane's kernels).
  std::vector<LearningFillet> fillets;
  std::vector<TradeoffPoint> tradeoff;  // one per target asked, in its order
};

// The lane's bank of kernels whitened by its product's texture (matched_kernels.h), learned
// from the clean fillets' z (one energy: a dual-energy lane's bone image keeps the
// Gaussian); empty when inspection.matched_kernels_mm is.
MatchedKernels learn_lane_kernels(const std::vector<FilletImage>& images,
                                  const InspectionParams& inspection);

// `inspection`: the lane's settings the fillets were inspected with. tradeoff_targets: other
// false-reject targets, each in (0, 0.5) (Error naming one that is not), whose thresholds
// and sensitivity are learned beside the lane's own; the test pieces of all of them are
// inspected once (measure_sensitivity_each).
LaneLearning learn_lane(const LearningSet& set, const InspectionParams& inspection,
                        const LearnOptions& lo, const SensitivityOptions& so,
                        const std::string& version, const std::string& learned_on,
                        const std::function<void(int, int)>& progress = {},
                        const std::vector<double>& tradeoff_targets = {});

// The learning's sensitivity claims checked on fillets it did not learn from (another
// recording of the same product): the pieces are injected into those that teach.
struct HeldOutCheck {
  int fillets = 0;                     // used for the check
  std::vector<ClaimCheck> checks;      // per band
  std::vector<StatedCheck> stated;     // the report's sentences
  std::vector<SensitivityCell> cells;  // what was found on the check fillets
  int held() const;
  int contradicted() const;  // by band: found too few to be the claimed rate's chance
};
HeldOutCheck check_held_out(const std::vector<InspectedFillet>& fillets, const LaneLearning& l,
                            const SensitivityOptions& so,
                            const std::function<void(int, int)>& progress = {});

// A new version's default name: learn-YYYYmmdd-HHMMSS (UTC).
std::string learning_version_name();

}  // namespace rangex
