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
// The sensitivity claims checked on held-out fillets.
nlohmann::json claim_checks_json(const std::string& recording, int fillets,
                                 const std::vector<ClaimCheck>& checks);
void write_learn_plots(const std::filesystem::path& dir, int lane, const ProductLearning& learning,
                       const SensitivityResult& sensitivity);
std::string learn_summary_text(int lane, const ProductLearning& learning,
                               const SensitivityResult& sensitivity);

}  // namespace rangex::cli
