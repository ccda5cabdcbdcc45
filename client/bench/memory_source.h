// One lane's lines rendered once into memory, sent as lane `lane`, `repeats` times over (the
// belt runs on: counts go on rising). The benchmarks' and the soak's line source.
#pragma once
#include <cstdint>
#include <vector>

#include "line_source.h"
#include "rangex/v1/rangex.pb.h"

namespace rangex::cli {

class MemorySource : public LineSource {
 public:
  MemorySource(const std::vector<v1::LineScan>& scans, int lane, int64_t repeats = 1)
      : scans_(scans), lane_(lane), repeats_(repeats) {}
  std::vector<int> lanes() const override { return {lane_}; }
  int64_t lines() const override { return int64_t(scans_.size()) * repeats_; }
  void line(int, int64_t n, v1::LineScan& out) override {
    const int64_t L = int64_t(scans_.size());
    out = scans_[size_t(n % L)];
    out.set_encoder(out.encoder() + (n / L) * L);
    out.set_lane(lane_);
  }

 private:
  const std::vector<v1::LineScan>& scans_;
  int lane_;
  int64_t repeats_;
};

// A lane's worth of simulated lines with `fillets` fillets in it, whole (the scene ends on
// empty belt, so that it can repeat without cutting a fillet), at most `max_lines`.
std::vector<v1::LineScan> render_lane_lines(const LaneConfig& lane, int fillets, int64_t max_lines,
                                            uint64_t seed = 1);

}  // namespace rangex::cli
