// What `rangexctl learn` (and the matrix) report of a product learning: JSON for machines,
// PNG plots (thresholds and sensitivity against thickness, the QQ plot of the learning
// fillets' extremes against the fitted model) and a few lines for people.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "pipeline/product_learning.h"
#include "pipeline/sensitivity.h"

namespace rangex::cli {

nlohmann::json learn_report_json(int lane, const ProductLearning& learning,
                                 const SensitivityResult& sensitivity);
void write_learn_plots(const std::filesystem::path& dir, int lane, const ProductLearning& learning,
                       const SensitivityResult& sensitivity);
std::string learn_summary_text(int lane, const ProductLearning& learning,
                               const SensitivityResult& sensitivity);

}  // namespace rangex::cli
