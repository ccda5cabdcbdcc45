// This process's resident memory (/proc/self/statm), sampled on a thread while a benchmark
// runs: how much a server holds per lane, and whether it grows while it works.
#pragma once
#include <atomic>
#include <cstdint>
#include <thread>
#include <utility>
#include <vector>

namespace rangex::cli {

int64_t resident_bytes();  // 0 where /proc is not readable

class ResidentSampler {
 public:
  explicit ResidentSampler(int period_ms = 50);
  ~ResidentSampler();
  ResidentSampler(const ResidentSampler&) = delete;
  ResidentSampler& operator=(const ResidentSampler&) = delete;
  // Stops sampling; (seconds since the start, bytes) of every sample.
  std::vector<std::pair<double, int64_t>> stop();

 private:
  std::atomic<bool> stop_{false};
  std::vector<std::pair<double, int64_t>> samples_;
  std::thread thread_;
};

}  // namespace rangex::cli
