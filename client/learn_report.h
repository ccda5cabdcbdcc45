// What `rangexctl learn` shows of a product learning beside its JSON report
// (pipeline/learned_report.h): PNG plots (thresholds and sensitivity against thickness, the
// QQ plot of the learning fillets' extremes against the fitted model) and a few lines for
// people, and what other false-reject targets would buy (--tradeoff).
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/lane_learning.h"
#include "pipeline/product_learning.h"
#include "pipeline/sensitivity.h"

namespace rangex::cli {

void write_learn_plots(const std::filesystem::path& dir, int lane, const ProductLearning& learning,
                       const SensitivityResult& sensitivity);
std::string learn_summary_text(int lane, const ProductLearning& learning,
                               const SensitivityResult& sensitivity);

// --keep 0:25,1:3: fillets a failed learning named that an operator checked and found
// clean (lane:fillet, as the learning names them).
std::vector<std::pair<int, int64_t>> checked_clean_fillets(const std::string& list);
// --tradeoff 0.001,0.01: false-reject targets beside the lane's, each a fraction in (0, 0.5).
std::vector<double> tradeoff_targets(const std::string& list);
// The learned target and each other one, a line each: the rate it implies, its thresholds'
// range, the sphere claimed by band and the report's sentences.
std::string tradeoff_text(const LaneLearning& learned, const std::vector<TradeoffPoint>& points);

}  // namespace rangex::cli
