// The lines a feeder sends, lane by lane in encoder order: from a recording, a simulation,
// or lines already in memory.
#pragma once
#include <memory>
#include <vector>

#include "core/plant_config.h"
#include "core/recording.h"
#include "rangex/v1/rangex.pb.h"

namespace rangex {

namespace sim {
struct SimulationParams;
class LaneSimulator;
}  // namespace sim

class LineSource {
 public:
  virtual ~LineSource() = default;
  virtual std::vector<int> lanes() const = 0;  // lane ids
  virtual int64_t lines() const = 0;           // per lane
  virtual void line(int lane_index, int64_t n, v1::LineScan& out) = 0;
};

class RecordingSource : public LineSource {
 public:
  explicit RecordingSource(const std::string& dir) : rec_(dir) {}
  std::vector<int> lanes() const override { return rec_.info().lanes; }
  int64_t lines() const override { return rec_.info().lines; }
  void line(int lane_index, int64_t n, v1::LineScan& out) override;

 private:
  RecordingReader rec_;
};

class SimulatedSource : public LineSource {
 public:
  SimulatedSource(const PlantConfig& plant, const sim::SimulationParams& p);
  ~SimulatedSource() override;
  std::vector<int> lanes() const override;
  int64_t lines() const override { return lines_; }
  void line(int lane_index, int64_t n, v1::LineScan& out) override;

 private:
  const PlantConfig& plant_;
  std::vector<sim::LaneSimulator> sims_;
  int64_t lines_ = 0;
};

}  // namespace rangex
