#include "pipeline/lane_learning.h"

#include <algorithm>
#include <ctime>

#include "core/error.h"
#include "pipeline/inspection_steps.h"
#include "pipeline/matched_kernels.h"

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

MatchedKernels learn_lane_kernels(const std::vector<FilletImage>& images,
                                  const InspectionParams& inspection) {
  if (inspection.matched_kernels_mm.empty() || images.empty()) return {};
  // Lags to twice the largest window's radius: the covariance over that window.
  const FilletImage& first = images.front();
  int radius = 0;
  auto window = [&](const char* key, const std::vector<double>& sizes_mm, const char* piece) {
    for (double d : sizes_mm) {
      const int r = kernel_radius(d, first.pitch_mm, first.step_mm);
      if (r > kMaxKernelRadius)
        fail("inspection.", key, ": a ", d, " mm ", piece, " needs a window of radius ", r,
             " px on ", first.pitch_mm, " mm pixels; at most ", kMaxKernelRadius);
      radius = std::max(radius, r);
    }
  };
  window("matched_kernels_mm", inspection.matched_kernels_mm, "sphere");
  window("matched_needles_mm", inspection.matched_needles_mm, "needle");
  InspectionParams plain = inspection;
  plain.learned = {};
  struct Seen {
    std::vector<float> z;
    std::vector<uint8_t> use;
    int rows, cols;
  };
  std::vector<Seen> seen;
  std::vector<double> bright;
  for (const FilletImage& img : images) {
    if (!img.xray_high.empty()) return {};
    FilletResult r;
    OneEnergyModel m;
    if (!start_inspection(img, plain, r) || !one_energy_model(img, plain, r, m)) continue;
    const FilletImage& at = m.image(img);
    bright.push_back(bright_quantile(m.z.data(), m.use.data(), m.z.size(), 0.999));
    seen.push_back({std::move(m.z), std::move(m.use), at.rows, at.cols});
  }
  // The level no texture of this product reaches, from its own fillets' brightest texture.
  const double void_level =
      learned_void_level(bright, inspection.matched_void_factor, inspection.matched_clip);
  TextureCovariance cov(2 * radius, inspection.matched_clip,
                        inspection.matched_enclosure ? radius : 0, void_level);
  for (const Seen& s : seen) cov.add(s.z.data(), s.use.data(), s.rows, s.cols);
  if (cov.fillets() == 0) return {};
  MatchedKernels k = learn_matched_kernels(cov, inspection.matched_kernels_mm, first.pitch_mm,
                                           first.step_mm, first.detector_sigma_px);
  learn_needle_kernels(cov, inspection.matched_needles_mm, inspection.matched_needle_diameters_mm,
                       first.pitch_mm, first.step_mm, first.detector_sigma_px, k);
  return k;
}

LaneLearning learn_lane(const LearningSet& set, const InspectionParams& inspection,
                        const LearnOptions& lo, const SensitivityOptions& so,
                        const std::string& version, const std::string& learned_on,
                        const std::function<void(int, int)>& progress,
                        const std::vector<double>& tradeoff_targets) {
  for (double t : tradeoff_targets)
    if (!(t > 0 && t < 0.5)) fail("a false-reject target must be in (0, 0.5) (got ", t, ")");
  LaneLearning out;
  // Round kernels whitened by this product's texture, when the lane asks for them: learned
  // from the same fillets' z, which are then inspected again with them for the extremes the
  // thresholds are fitted to.
  const MatchedKernels kernels = learn_lane_kernels(set.images, inspection);
  std::vector<LearningFillet> fillets = set.fillets;
  if (!kernels.empty()) {
    InspectionParams with = inspection;
    with.learned = {};
    with.learned.matched = kernels;
    with.band_extremes = true;
    for (size_t i = 0; i < set.images.size(); ++i)
      fillets[i].extremes = inspect_fillet(set.images[i], with, false).extremes;
  }
  out.fillets = fillets;
  out.learning = learn_product(fillets, lo);
  out.learning.learned.matched = kernels;
  out.learning.learned.version = version;
  out.learning.learned.learned_on = learned_on;
  out.inspection = inspection;
  out.inspection.learned = out.learning.learned;
  // Each other target's thresholds from the same fillets' models, with the same kernels.
  std::vector<LearnedDetection> sets = {out.learning.learned};
  for (double target : tradeoff_targets) {
    TradeoffPoint t;
    t.target_frr = target;
    LearnOptions at = lo;
    at.target_frr = target;
    t.learned = learn_product(out.fillets, at).learned;
    t.learned.matched = kernels;
    t.learned.version = version, t.learned.learned_on = learned_on;
    t.implied_frr = implied_false_reject_rate(t.learned);
    sets.push_back(t.learned);
    out.tradeoff.push_back(std::move(t));
  }
  if (!out.learning.ok && !so.when_learning_failed) {
    out.sensitivity.summary = {"not measured: the learning failed"};  // inspections: 0
    return out;
  }
  std::vector<SensitivityResult> sens =
      measure_sensitivity_each(set.sensitivity_fillets(), out.inspection, sets, so, progress);
  out.sensitivity = std::move(sens[0]);
  out.learning.learned.sensitivity = out.sensitivity.summary;
  for (size_t k = 0; k < out.tradeoff.size(); ++k) {
    out.tradeoff[k].sensitivity = std::move(sens[k + 1]);
    out.tradeoff[k].learned.sensitivity = out.tradeoff[k].sensitivity.summary;
  }
  return out;
}

int HeldOutCheck::held() const {
  int n = 0;
  for (const ClaimCheck& k : checks) n += k.held;
  return n;
}

int HeldOutCheck::contradicted() const {
  int n = 0;
  for (const ClaimCheck& k : checks) n += k.contradicted;
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
  c.stated = check_stated_claims(l.sensitivity.stated, on_held, so.rate);
  c.cells = on_held.cells;
  return c;
}

std::string learning_version_name() {
  const std::time_t now = std::time(nullptr);
  char b[40];
  std::strftime(b, sizeof b, "learn-%Y%m%d-%H%M%S", std::gmtime(&now));
  return b;
}

}  // namespace rangex
