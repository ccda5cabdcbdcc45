// The matrix's report over the variants run so far (client/cmd_eval_matrix.cpp).
#pragma once
#include <string>
#include <vector>

#include "eval_matrix_row.h"

namespace rangex::cli {

// The text: each variant's thickness, recall and false rejects beside the X-ray-only
// baseline, the learned rows, the bone runs and the acceptance targets.
std::string matrix_text(const std::vector<MatrixRow>& rows, const MatrixOptions& mo);

// The same as JSON (matrix.json).
std::string matrix_json(const std::vector<MatrixRow>& rows);

}  // namespace rangex::cli
