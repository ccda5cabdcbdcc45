#include "pipeline/lane_learning.h"

#include <ctime>

namespace rangex {

bool LearningSet::teaches(const FilletResult& r) {
  return r.decision != Decision::kNotInspected && r.fitted;
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

std::string learning_version_name() {
  const std::time_t now = std::time(nullptr);
  char b[40];
  std::strftime(b, sizeof b, "learn-%Y%m%d-%H%M%S", std::gmtime(&now));
  return b;
}

}  // namespace rangex
