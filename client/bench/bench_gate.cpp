#include "bench/bench_gate.h"

#include <cmath>
#include <cstdio>
#include <string>

namespace rangex::cli {

BenchGate::BenchGate(PlantConfig& plant, double lines_per_s) : rate_(lines_per_s) {
  plc_ = std::make_unique<SimPlc>(plant.plc);
  plant.plc.address = "127.0.0.1:" + std::to_string(plc_->port());
  cfg_ = plant.plc;
  for (const LaneConfig& l : plant.lanes) step_mm_[l.id] = l.encoder_step_mm;
  mover_ = std::thread([this] {
    while (!stop_) {
      {
        const auto now = std::chrono::steady_clock::now();
        std::lock_guard<std::mutex> lk(mu_);
        for (const auto& [lane, b] : belts_)
          plc_->belt(lane,
                     b.first + int64_t(std::floor(
                                   rate_ * std::chrono::duration<double>(now - b.t0).count())));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
}

BenchGate::~BenchGate() {
  stop_ = true;
  mover_.join();
}

void BenchGate::start_lane(int lane, int64_t first_encoder) {
  std::lock_guard<std::mutex> lk(mu_);
  belts_[lane] = {first_encoder, std::chrono::steady_clock::now()};
}

uint64_t BenchGate::report(const PlcStatus& rangexd, int64_t decided) {
  uint64_t in_time = 0, pass_late = 0, rejected = 0, not_inspected = 0, late = 0;
  int64_t least_spare = INT64_MAX;
  const auto got = plc_->received();
  for (const SimPlc::Received& r : got) {
    // The fillet's leading edge reaches the gate reject_station_mm past the X-ray plane.
    const auto step = step_mm_.find(r.release.lane);
    if (step == step_mm_.end()) continue;
    const int64_t gate =
        r.release.first_encoder + int64_t(std::floor(cfg_.reject_station_mm / step->second));
    switch (r.release.code) {
      case ReleaseCode::kPass:
        if (r.belt < gate) {
          ++in_time;
          least_spare = std::min(least_spare, gate - r.belt);
        } else {
          ++pass_late;
        }
        break;
      case ReleaseCode::kReject:
        ++rejected;
        break;
      case ReleaseCode::kNotInspected:
        ++not_inspected;
        break;
      case ReleaseCode::kLate:
        ++late;
        break;
    }
  }
  const int64_t unsent = decided - int64_t(got.size());
  std::printf(
      "   PLC gate: %lld decided, %zu releases at the PLC: %llu passes in time (least spare %s), "
      "%llu passes after the gate, %llu late (sent as late), %llu rejected, %llu not inspected; "
      "%lld never sent\n",
      (long long)decided, got.size(), (unsigned long long)in_time,
      least_spare == INT64_MAX ? "none"
                               : (std::to_string(least_spare) + " lines, " +
                                  std::to_string(int(1e3 * double(least_spare) / rate_)) + " ms")
                                     .c_str(),
      (unsigned long long)pass_late, (unsigned long long)late, (unsigned long long)rejected,
      (unsigned long long)not_inspected, (long long)unsent);
  std::printf(
      "   rangexd's PLC counts: %llu released, %llu diverted, %llu late, %llu unreleased, "
      "%llu reconnects, least spare %.0f ms\n",
      (unsigned long long)rangexd.released, (unsigned long long)rangexd.diverted,
      (unsigned long long)rangexd.late, (unsigned long long)rangexd.unreleased,
      (unsigned long long)rangexd.reconnects, rangexd.least_spare_ms);
  return pass_late + late + rangexd.unreleased;
}

}  // namespace rangex::cli
