// Where a lane's lines come from when rangexd takes them from the sensors itself (plant.yaml
// lanes[].sources): two GigE Vision laser cameras and the X-ray line-scan detector, each an
// Aravis device id or an IP address. A lane without sources is fed over gRPC (StreamLines).
#pragma once
#include <string>
#include <vector>

namespace rangex {

enum class LineTrigger {
  kEncoder,  // a line per encoder pulse on the devices' trigger input (a real line)
  kFreeRun,  // the devices' own rate, frame ids as counts (bench set-ups, fake cameras)
};

struct SensorSources {
  std::vector<std::string> cameras;  // exactly two when set
  std::string xray;
  LineTrigger trigger = LineTrigger::kEncoder;
  std::string trigger_line = "Line0";  // the input the encoder is wired to (TriggerSource)
  int offset_y = -1;                   // the stripe window's first sensor row (-1: leave it)
  double exposure_us = 0;              // 0: leave the devices' own
  int packet_size = 0;                 // GVSP packet bytes (0: negotiated with the device)

  bool enabled() const { return !cameras.empty(); }
  // Cameras first, then the X-ray detector (none when fed over gRPC).
  std::vector<std::string> devices() const {
    if (!enabled()) return {};
    std::vector<std::string> d = cameras;
    d.push_back(xray);
    return d;
  }
};

const char* trigger_name(LineTrigger t);

}  // namespace rangex
