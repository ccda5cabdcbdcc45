// bench --path: the whole in-process line path on the CPU, stage by stage (ingest copy,
// stripe, rectify, fuse, project, assemble, and the inspection's fit, detector match, noise
// model, smoothing and components), per line and per fillet, as a share of the total and as
// a fraction of each stage's own memory bound (its bytes at the read bandwidth measured in
// the same run), for 1/4/16 lanes on one core, and the two-core scaling.
#pragma once
#include <vector>

#include "core/plant_config.h"

namespace rangex::cli {

struct PathBenchOptions {
  std::vector<int> lanes = {1, 4, 16};
  int lines = 1024;  // distinct simulated lines per lane (256 kB of frames each)
  int batch = 64;    // lines per batch, lanes mixed as the server mixes them
  int threads = 2;   // the scaling run: lanes split over this many threads
};

int bench_path(const PlantConfig& plant, const PathBenchOptions& opt);

}  // namespace rangex::cli
