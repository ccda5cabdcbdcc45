// The scattering constants K1, K2 of one camera ("Laser Range Imaging ...", section 5.4.2)
// fitted from a recording with truth, where the simulator's true stripe stands in for the
// coated reference profiles of the dissertation; and the report that makes them a lane's
// calibration.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "calib/scatter_constants.h"
#include "calib/solve_report.h"
#include "core/plant_config.h"
#include "core/recording.h"

namespace rangex {

struct ScatterFromTruthOptions {
  int64_t lines = 0;  // per lane, from the first (0: all)
  // The constants describe scattering in meat: only columns whose reference point lies on
  // the fillet (above this height) take part; the belt barely scatters.
  double min_height_mm = 1.0;
};

// Every lane of the recording; lanes[i] is the calibration of the recording's i-th lane.
ScatterFit fit_scatter_from_truth(const RecordingReader& rec, int cam,
                                  const std::vector<LaneConfig>& lanes,
                                  const ScatterFromTruthOptions& opt);

// The fit as a lane camera's calibration (`lane` takes the constants) and its report; a fit
// that leaves the stripe worse than the plain centroid fails.
SolveReport apply_scatter_fit(LaneConfig& lane, int cam, const ScatterFit& f,
                              const std::string& fitted_on);

}  // namespace rangex
