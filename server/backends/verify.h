// What a backend's results may differ from the CPU reference's, stage by stage, and the
// comparison the server runs on a fraction of its batches (and the suite on every case).
// Flags, peaks and widths are integers on both sides and must be equal; positions may differ
// by float rounding in a different order of operations.
#pragma once
#include <optional>
#include <string>

#include "pipeline/line_pipeline.h"

namespace rangex {

struct Tolerance {
  static constexpr double kRowPx = 1e-4;        // stripe row, centroid, asymmetry (px)
  static constexpr double kRectifiedMm = 1e-4;  // rectified x, z (mm)
  static constexpr double kProfileMm = 1e-4;    // fused height (mm)
  static constexpr double kThicknessMm = 1e-3;  // X-ray path thickness (mm)
};

struct Mismatch {
  std::string what;  // "thickness", "thickness valid", "stripe row", ...
  size_t index = 0;  // the first differing item
  size_t line = 0;   // the batch line it belongs to
  double got = 0, want = 0;
  std::string describe() const;
};

// The first item where `got` differs from `want` beyond its stage's tolerance (NaN equals
// NaN), over the stripes and the thickness lines of a batch of `lines` lines.
std::optional<Mismatch> compare_line_results(const LineResults& got, const LineResults& want,
                                             int lines);

}  // namespace rangex
