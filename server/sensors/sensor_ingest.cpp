#include "sensors/sensor_ingest.h"

namespace rangex {

SensorIngest::SensorIngest(const PlantConfig& plant,
                           const std::function<LaneSink(int lane)>& sink_of, SensorOptions opt) {
  for (const LaneConfig& l : plant.lanes)
    if (l.sources.enabled()) lanes_.push_back(std::make_unique<GigeLane>(l, sink_of(l.id), opt));
}

SensorIngest::~SensorIngest() = default;

void SensorIngest::stop() {
  for (auto& l : lanes_) l->stop();
}

std::vector<LaneSensors> SensorIngest::state() const {
  std::vector<LaneSensors> out;
  for (const auto& l : lanes_) out.push_back(l->state());
  return out;
}

bool has_sensor_lanes(const PlantConfig& plant) {
  for (const LaneConfig& l : plant.lanes)
    if (l.sources.enabled()) return true;
  return false;
}

}  // namespace rangex
