// p50/p99 of the most recent samples of a stage's latency (a ring of 4096).
#pragma once
#include <algorithm>
#include <cstdint>
#include <mutex>
#include <vector>

namespace rangex {

class LatencyStats {
 public:
  void add(double ms) {
    std::lock_guard<std::mutex> lock(mu_);
    if (ring_.size() < kCap)
      ring_.push_back(ms);
    else
      ring_[next_++ % kCap] = ms;
    ++count_;
  }
  struct Summary {
    double p50 = 0, p99 = 0;
    uint64_t samples = 0;
  };
  Summary summary() {
    std::vector<double> v;
    uint64_t n;
    {
      std::lock_guard<std::mutex> lock(mu_);
      v = ring_;
      n = count_;
    }
    Summary s;
    s.samples = n;
    if (v.empty()) return s;
    std::sort(v.begin(), v.end());
    s.p50 = v[v.size() / 2];
    s.p99 = v[std::min(v.size() - 1, size_t(0.99 * double(v.size())))];
    return s;
  }

 private:
  static constexpr size_t kCap = 4096;
  std::mutex mu_;
  std::vector<double> ring_;
  size_t next_ = 0;
  uint64_t count_ = 0;
};

}  // namespace rangex
