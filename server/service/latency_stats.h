// A stage's latency: p50/p99 of the most recent samples (a ring of 4096), and a histogram of
// every sample since the start (cumulative counts at fixed bounds, and their sum), the shape
// Prometheus expects of a histogram.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <mutex>
#include <vector>

namespace rangex {

class LatencyStats {
 public:
  // Upper bounds of the histogram's buckets, ms; a last bucket (+Inf) holds every sample.
  // Fine from 10 to 200 ms, where a plant's decisions fall, so that quantiles read off the
  // buckets (Prometheus' histogram_quantile, the soak's per-minute figures) are close.
  static constexpr std::array<double, 23> kBoundsMs = {0.5, 1,   2,   5,    10,   20,   30,   40,
                                                       50,  60,  70,  80,   90,   100,  125,  150,
                                                       200, 300, 500, 1000, 2000, 5000, 10000};

  void add(double ms) {
    std::lock_guard<std::mutex> lock(mu_);
    if (ring_.size() < kCap)
      ring_.push_back(ms);
    else
      ring_[next_++ % kCap] = ms;
    ++count_;
    sum_ms_ += ms;
    const size_t b =
        size_t(std::lower_bound(kBoundsMs.begin(), kBoundsMs.end(), ms) - kBoundsMs.begin());
    ++buckets_[b];
  }
  struct Summary {
    double p50 = 0, p99 = 0;  // of the most recent samples
    uint64_t samples = 0;     // since the start
    double sum_ms = 0;        // of every sample
    // Samples <= kBoundsMs[k], cumulative (the +Inf bucket is `samples`).
    std::array<uint64_t, kBoundsMs.size()> cumulative{};
  };
  Summary summary() const {
    std::vector<double> v;
    Summary s;
    {
      std::lock_guard<std::mutex> lock(mu_);
      v = ring_;
      s.samples = count_;
      s.sum_ms = sum_ms_;
      uint64_t c = 0;
      for (size_t k = 0; k < kBoundsMs.size(); ++k) s.cumulative[k] = c += buckets_[k];
    }
    if (v.empty()) return s;
    std::sort(v.begin(), v.end());
    s.p50 = v[v.size() / 2];
    s.p99 = v[std::min(v.size() - 1, size_t(0.99 * double(v.size())))];
    return s;
  }

 private:
  static constexpr size_t kCap = 4096;
  mutable std::mutex mu_;
  std::vector<double> ring_;
  size_t next_ = 0;
  uint64_t count_ = 0;
  double sum_ms_ = 0;
  std::array<uint64_t, kBoundsMs.size() + 1> buckets_{};  // the last: above every bound
};

}  // namespace rangex
