// `rangexctl bench --backend NAME|all`: each line stage on each backend, for 1, 4 and 16
// lanes and batches of 1 to 256 lines, split into upload / compute / download, beside the
// CPU backend measured in the same run; the whole line path with two batches in flight;
// and each device's host-to-device bandwidth, against which its stripe stage is set.
#pragma once
#include <string>
#include <vector>

#include "core/plant_config.h"

namespace rangex::cli {

struct BackendBenchOptions {
  std::vector<std::string> backends;  // the CPU first: the others are measured against it
  std::string device;
  int threads = 1;        // the CPU backend's stripe workers
  double seconds = 0.25;  // per measured cell
  std::vector<int> lanes{1, 4, 16};
  std::vector<int> batches{1, 16, 64, 256};
};

int bench_backends(const PlantConfig& plant, const BackendBenchOptions& opt);

}  // namespace rangex::cli
