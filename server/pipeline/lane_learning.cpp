#include "pipeline/lane_learning.h"

#include <ctime>

namespace rangex {

bool LearningSet::teaches(const FilletResult& r) {
  return r.decision != Decision::kNotInspected && (r.fitted || r.dual_energy);
}

void LearningSet::add(const FilletResult& r, FilletImage image) {
  if (!teaches(r)) {
    ++not_inspected;
    return;
  }
  fillets.push_back({r.lane, r.id, r.y0_mm, r.extremes});
  images.push_back(std::move(image));
  fits.push_back({r.fit.beta1, r.fit.beta2});
}

std::vector<SensitivityFillet> LearningSet::sensitivity_fillets() const {
  std::vector<SensitivityFillet> v;
  for (size_t i = 0; i < images.size(); ++i)
    v.push_back({&images[i], fits[i].first, fits[i].second});
  return v;
}

LaneLearning learn_lane(const LearningSet& set, const InspectionParams& inspection,
                        const LearnOptions& lo, const SensitivityOptions& so,
                        const std::string& version, const std::string& learned_on,
                        const std::function<void(int, int)>& progress) {
  LaneLearning out;
  out.learning = learn_product(set.fillets, lo);
  out.learning.learned.version = version;
  out.learning.learned.learned_on = learned_on;
  out.inspection = inspection;
  out.inspection.learned = out.learning.learned;
  out.sensitivity = measure_sensitivity(set.sensitivity_fillets(), out.inspection, so, progress);
  out.learning.learned.sensitivity = out.sensitivity.summary;
  return out;
}

int HeldOutCheck::held() const {
  int n = 0;
  for (const ClaimCheck& k : checks) n += k.held;
  return n;
}

HeldOutCheck check_held_out(const std::vector<InspectedFillet>& fillets, const LaneLearning& l,
                            const SensitivityOptions& so,
                            const std::function<void(int, int)>& progress) {
  std::vector<SensitivityFillet> held;
  for (const InspectedFillet& f : fillets)
    if (LearningSet::teaches(f.result))
      held.push_back({&f.image, f.result.fit.beta1, f.result.fit.beta2});
  HeldOutCheck c;
  c.fillets = int(held.size());
  const SensitivityResult on_held = measure_sensitivity(held, l.inspection, so, progress);
  c.checks = check_claims(l.sensitivity.claims, on_held, so.rate);
  return c;
}

std::string learning_version_name() {
  const std::time_t now = std::time(nullptr);
  char b[40];
  std::strftime(b, sizeof b, "learn-%Y%m%d-%H%M%S", std::gmtime(&now));
  return b;
}

}  // namespace rangex
