// GigE Vision devices without a line: Aravis's ArvGvFakeCamera in this process, each on its
// own loopback address (GVCP listens on port 3956, so one device per address), serving the
// frames of a recording, pulsed by an encoder of their own. rangexd connects to them over
// GVCP/GVSP as it would to a camera. For the tests, the demo and an integrator's dry run of
// a plant.yaml (`rangexctl fake-lane`).
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/recording.h"

namespace rangex {

// Adds the addresses `lo` lacks (ip addr add A/32 dev lo) and removes them afterwards. Needs
// root (or sudo without a password); error() says why not.
class LoopbackAddresses {
 public:
  explicit LoopbackAddresses(std::vector<std::string> addresses);
  ~LoopbackAddresses();
  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }

 private:
  std::vector<std::string> added_;
  std::string error_;
};

// One lane's recording as its devices' frames: at the lane's encoder pulse n (0 for the
// first) the belt shows the recording's line n - lead. Before the lead the devices show line
// 0, after the end the last line.
class ServedLane {
 public:
  ServedLane(const RecordingReader& rec, int lane, int lead_frames = 25);
  // Fills device `d`'s frame (0, 1: cameras; 2: X-ray, one row a layer: a recording of two
  // energies serves the low row, then the high) at pulse n.
  void fill(int d, int64_t n, uint8_t* out, size_t bytes);
  // rangexd counts frames from 1, the devices starting together at pulse 0: the count that
  // shows line 0.
  int64_t start() const { return lead_ + 1; }
  int64_t lines() const { return lines_; }
  const uint8_t* frame(int d, int64_t line) const;  // what fill() serves for a line

 private:
  RecordingReader::MappedFrames frames_;
  std::vector<uint16_t> xray_;
  size_t frame_bytes_ = 0, xray_pixels_ = 0;
  int energies_ = 1;
  int64_t lines_ = 0;
  int lead_ = 25;
};

// One ArvGvFakeCamera on `address`, its frames filled by `fill` (n: the frame's number, 0 for
// the device's first). Free running it sends a frame every `period_us`; triggered (TriggerMode
// On, TriggerSource Software, as rangexd sets `trigger: encoder` with `trigger_line: Software`)
// it sends one per trigger() and looks for one every `period_us`. `genicam_file`: a
// description to serve instead of Aravis's own (a device that lacks a feature).
class FakeDevice {
 public:
  using Fill = std::function<void(int64_t n, uint8_t* data, size_t bytes)>;
  FakeDevice(const std::string& address, const std::string& serial, int period_us, Fill fill,
             const std::string& genicam_file = "");
  ~FakeDevice();
  void set_packet_loss(double ratio);
  // Writes its first GenICam URL register (0x200), as a device naming another description.
  void set_genicam_url(const std::string& url);
  void trigger();                // an encoder pulse
  bool trigger_pending() const;  // not yet taken
  bool acquiring() const;        // a controller started acquisition
  // Aravis's own GenICam description of the fake camera.
  static std::string genicam_xml();

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// A lane's encoder. The belt stands until every device of the lane is acquiring (as a line
// is started); then each pulse goes to every device, and the next waits (up to half a
// second) until each has taken it, so that the lane's devices send their frames in step
// whatever the load on the machine. A device that is gone is not waited for; one that is
// back but not yet acquiring stops the belt again.
class FakeEncoder {
 public:
  explicit FakeEncoder(std::vector<std::unique_ptr<FakeDevice>>& devices);
  ~FakeEncoder();
  // Replaces device d (null: none) between pulses.
  void replace(size_t d, std::unique_ptr<FakeDevice> device);
  int64_t pulse() const { return pulses_; }  // the pulse the devices are showing (0: first)

 private:
  std::vector<std::unique_ptr<FakeDevice>>& devices_;
  std::mutex mu_;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> pulses_{0};
  std::thread thread_;
};

}  // namespace rangex
