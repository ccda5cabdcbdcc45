#include "bench/resident_memory.h"

#include <unistd.h>

#include <chrono>
#include <fstream>

namespace rangex::cli {

int64_t resident_bytes() {
  std::ifstream f("/proc/self/statm");
  int64_t size = 0, resident = 0;
  if (!(f >> size >> resident)) return 0;
  return resident * int64_t(sysconf(_SC_PAGESIZE));
}

ResidentSampler::ResidentSampler(int period_ms) {
  thread_ = std::thread([this, period_ms] {
    const auto t0 = std::chrono::steady_clock::now();
    while (!stop_) {
      const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      samples_.emplace_back(t, resident_bytes());
      std::this_thread::sleep_for(std::chrono::milliseconds(period_ms));
    }
  });
}

ResidentSampler::~ResidentSampler() {
  stop();
}

std::vector<std::pair<double, int64_t>> ResidentSampler::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  return samples_;
}

}  // namespace rangex::cli
