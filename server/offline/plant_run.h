// A simulated plant processed in memory: each lane's lines are rendered by the simulator and
// go straight through the same LaneProcessor as a recording would, so that hundreds of
// fillets can be evaluated without writing gigabytes of frames. Line accuracy (stripe,
// thickness) is measured on the fly against the simulator's truth.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "backends/registry.h"
#include "core/plant_config.h"
#include "offline/evaluation.h"
#include "offline/fillet_records.h"
#include "pipeline/lane_processor.h"
#include "sim/plant_simulator.h"

namespace rangex {

struct PlantRunLane {
  int lane = 0;
  int64_t lines = 0;
  RecordSet ours, baseline;
  LaneEvaluation accuracy;  // stripe and thickness errors against truth
  AssemblyStats assembly;
  FusionStats fusion;
  double render_s = 0, pipeline_s = 0, inspection_s = 0;
  std::string truth_fragments_csv, truth_fillets_csv;
};

struct PlantRunOptions {
  int threads = 1;                         // rendering workers
  BackendRequest backend = cpu_request();  // where the line stages run
  bool keep_images = false;
  // Called for every inspected fillet (e.g. to write its images).
  std::function<void(const InspectedFillet&)> on_fillet;
};

// `backend_info`, when given, receives what the line stages ran on.
std::vector<PlantRunLane> run_simulated_plant(
    const PlantConfig& plant, const sim::SimulationParams& sim, const PlantRunOptions& opt,
    const std::function<void(int64_t, int64_t)>& progress = {},
    BackendInfo* backend_info = nullptr);

// Line accuracy of a lane as a small key,value CSV (for `rangexctl eval` of a simulated run).
void write_line_accuracy(const std::string& path, const LaneEvaluation& e);
LaneEvaluation read_line_accuracy(const std::string& path, int lane);

}  // namespace rangex
