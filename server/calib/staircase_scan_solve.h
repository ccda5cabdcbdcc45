// Both cameras' poses from a staircase scan (staircase.yaml beside it), or the steps as a
// calibration measures them (validate), with each step's error drawn as a plot (the
// dissertation's Table 5 as a picture); and a blocks scan (blocks.yaml) measured under a
// calibration as it stands.
#pragma once
#include <string>

#include "calib/registration_fit.h"
#include "calib/staircase_fit.h"
#include "core/plant_config.h"
#include "core/recording.h"

namespace rangex {

struct StaircaseScanSolve {
  Staircase drawing;
  StaircaseFit fits[2];
  SolveReport reports[2];
};

// With `solve`, each camera's pose is fitted and the lane takes both (the laser plane then
// defines the frame: y = 0); without, the steps are measured with the lane's cameras. The
// plot goes to `steps_png`.
StaircaseScanSolve solve_staircase_scan(const RecordingReader& rec, int lane, LaneConfig& lc,
                                        bool solve, const std::string& steps_png);

// The registration of a blocks scan under the lane's calibration: its cameras, delay and
// plane angles held, the stripe's erosion at the blocks' ends measured on this scan.
RegistrationFit check_blocks_scan(const RecordingReader& rec, int lane, const LaneConfig& lc);

// The registration solved from a blocks scan; the lane takes its cameras, delay and angles.
RegistrationFit solve_blocks_scan(const RecordingReader& rec, int lane, LaneConfig& lc);

}  // namespace rangex
