// The integrator's calibration files: a lane's calibration YAML (the sections of
// plant.yaml) read over the plant's lane, written back after each solve, and the solvers'
// reports kept beside it in <file>.reports/ (one JSON per solver and subject).
#pragma once
#include <string>

#include "calib/solve_report.h"
#include "core/plant_config.h"

namespace rangex {

// FILE over the plant's lane, or the plant's lane itself when FILE is empty or absent.
LaneConfig load_lane_calibration(const PlantConfig& plant, int lane, const std::string& file);
// FILE (every lane) or L:FILE,L:FILE applied over the plant's lanes.
void apply_calibration_option(PlantConfig& plant, const std::string& value);
void save_lane_calibration(const LaneConfig& lane, const std::string& file,
                           const SolveReport& report);
// Every report saved beside `file`, as one {"reports": [...]} document ("" when none).
std::string lane_reports_json(const std::string& file);

}  // namespace rangex
