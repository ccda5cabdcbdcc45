// What a lane's sensors are doing, as ListLanes, /metrics and the dashboard show it: plain
// values, so that the service's headers need nothing of Aravis.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace rangex {

// One device as the lane shows it.
struct SensorState {
  std::string role;                  // cam0, cam1, xray
  std::string device;                // as configured (id or address)
  std::string description;           // vendor model #serial, once connected
  std::string state = "connecting";  // connecting | streaming | lost | refused | stopped
  std::string error;                 // why the last session ended or failed ("" : none)
  uint64_t frames = 0;               // complete frames taken
  uint64_t incomplete = 0;           // frames with lost packets (given back: missing lines)
  uint64_t lost_frames = 0;          // frames the ids say never arrived
  uint64_t wrong_format = 0;         // frames not of the configured format or size
  uint64_t lacked = 0;               // lines given up because this device lacked its frame
  uint64_t stale = 0;                // frames behind the device's own last count
  uint64_t underruns = 0;            // frames dropped for want of a free receive buffer
  uint64_t reconnects = 0;           // sessions after the first
};

struct LaneSensors {
  int lane = 0;
  std::string trigger;
  uint64_t lines = 0;       // complete lines handed to the engine
  uint64_t incomplete = 0;  // counts given up (a device lacked its frame)
  uint64_t refused = 0;     // lines the engine refused (its statistics say why)
  std::vector<SensorState> devices;
};

}  // namespace rangex
