// What `rangexctl learn` shows of a product learning beside its JSON report
// (pipeline/learned_report.h): PNG plots (thresholds and sensitivity against thickness, the
// QQ plot of the learning fillets' extremes against the fitted model) and a few lines for
// people.
#pragma once
#include <filesystem>
#include <string>

#include "pipeline/product_learning.h"
#include "pipeline/sensitivity.h"

namespace rangex::cli {

void write_learn_plots(const std::filesystem::path& dir, int lane, const ProductLearning& learning,
                       const SensitivityResult& sensitivity);
std::string learn_summary_text(int lane, const ProductLearning& learning,
                               const SensitivityResult& sensitivity);

}  // namespace rangex::cli
