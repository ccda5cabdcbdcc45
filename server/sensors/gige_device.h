// One GigE Vision device of a lane, through Aravis: opened by device id or IP address, its
// GenICam features set for its role at start (a feature the device refuses is named), its
// frames streamed into receive buffers that the lines borrow until they are staged. Aravis
// and GLib stay inside gige_device.cpp.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "core/line_bytes.h"
#include "core/sensor_sources.h"

namespace rangex {

enum class DeviceRole { kCamera, kXray };
const char* role_name(DeviceRole r, int index);  // "cam0", "cam1", "xray"

struct DeviceSetup {
  std::string id;  // Aravis device id or IP address
  DeviceRole role = DeviceRole::kCamera;
  int width = 0, height = 0;  // a camera's frame window; the X-ray detector: pixels x 1
  LineTrigger trigger = LineTrigger::kEncoder;
  std::string trigger_line = "Line0";
  int offset_y = -1;
  double exposure_us = 0;
  int packet_size = 0;
  int buffers = 128;  // receive buffers (a line holds its frames until staged)
};

struct DeviceFrame {
  // The frame's ChunkEncoderValue where the device sends one (`from_encoder`), else the
  // device's frames since this session started, lost ones included (1 for the first).
  int64_t count = 0;
  bool from_encoder = false;
  uint64_t lost_before = 0;  // frames the device's ids say were lost just before this one
  uint64_t id = 0;           // the GVSP frame (block) id
  LineBytes bytes;           // lent by the receive buffer
};

// What the stream says about the frames it received.
struct DeviceStreamCounts {
  uint64_t completed = 0, failures = 0, underruns = 0;
};

class GigeDevice {
 public:
  // Opens, configures and starts streaming; throws Error naming the device and, when it
  // refuses one, the feature and value.
  explicit GigeDevice(const DeviceSetup& setup);
  ~GigeDevice();
  GigeDevice(const GigeDevice&) = delete;
  GigeDevice& operator=(const GigeDevice&) = delete;

  enum class Got { kFrame, kNothing, kIncomplete, kWrongFormat };
  // Waits up to `timeout_ms` for the next frame. kIncomplete: lost packets (the frame is given
  // back); kWrongFormat: not the configured pixel format or size (`why` says what came).
  Got next(int timeout_ms, DeviceFrame& out, std::string& why);
  // False when the device stopped answering (control lost, or a register read failed).
  bool answering();
  DeviceStreamCounts stream_counts() const;
  const std::string& description() const;  // vendor, model, serial

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rangex
