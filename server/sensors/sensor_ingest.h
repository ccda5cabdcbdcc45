// Every lane of the plant that names its sensors (plant.yaml lanes[].sources) fed by them;
// the other lanes are fed over gRPC. Both ways meet in the same engine.
#pragma once
#include <functional>
#include <memory>
#include <vector>

#include "core/plant_config.h"
#include "sensors/gige_lane.h"

namespace rangex {

class SensorIngest {
 public:
  SensorIngest(const PlantConfig& plant, const std::function<LaneSink(int lane)>& sink_of,
               SensorOptions opt = {});
  ~SensorIngest();
  bool empty() const { return lanes_.empty(); }
  void stop();  // every device stops; the states stay readable
  std::vector<LaneSensors> state() const;

 private:
  std::vector<std::unique_ptr<GigeLane>> lanes_;
};

// Whether any lane of the plant takes its lines from its sensors.
bool has_sensor_lanes(const PlantConfig& plant);

}  // namespace rangex
