// Recordings: a folder with recording.yaml and raw little-endian arrays
// per lane: lane<ID>/cam0.u8, cam1.u8 (N x H x W), xray.u16 (N x D), encoder.i64 (N), and
// optionally lane<ID>/truth/ from the simulator. A dual-energy recording (xray_energies: 2 in
// recording.yaml) has xray_high.u16 (N x D) beside xray.u16, which is then the low line.
#pragma once
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "core/mapped_file.h"

namespace rangex {

struct RecordingInfo {
  std::vector<int> lanes;
  int width = 640;
  int height = 200;
  int xray_pixels = 480;
  int xray_energies = 1;  // 2: xray_high.u16 beside xray.u16
  int64_t lines = 0;      // per lane
  double encoder_step_mm = 0.4;
  std::string calibration_id;
  bool has_truth = false;
  uint64_t seed = 0;
};

// One line of one lane as stored: both camera frames, the X-ray line and the encoder count.
struct LineView {
  const uint8_t* cam0;
  const uint8_t* cam1;
  const uint16_t* xray;
  int64_t encoder;
  const uint16_t* xray_high = nullptr;  // a dual-energy recording's high line
};

class RecordingWriter {
 public:
  // Creates dir (and lane folders); refuses a folder that already holds a recording.
  RecordingWriter(const std::string& dir, RecordingInfo info);
  ~RecordingWriter();
  void append(int lane, const LineView& line);
  // Truth arrays are appended as raw bytes to lane<ID>/truth/<name>.
  void append_truth(int lane, const std::string& name, const void* data, size_t bytes);
  void write_truth_text(int lane, const std::string& name, const std::string& text);
  void close();  // writes recording.yaml with the final line count

 private:
  struct LaneFiles;
  std::string dir_;
  RecordingInfo info_;
  std::vector<std::unique_ptr<LaneFiles>> lanes_;
  bool closed_ = false;
  LaneFiles& files(int lane);
};

class RecordingReader {
 public:
  // Reads recording.yaml and checks that every array holds exactly `lines` records; a
  // truncated or oversized file is refused with the lane, file and sizes in the message.
  explicit RecordingReader(const std::string& dir);
  const RecordingInfo& info() const { return info_; }
  const std::string& dir() const { return dir_; }

  // Reads `count` lines from `first` of one lane into the caller's buffers.
  void read(int lane, int64_t first, int64_t count, uint8_t* cam0, uint8_t* cam1, uint16_t* xray,
            int64_t* encoder) const;
  // A dual-energy recording's high lines (throws for a recording of one energy).
  void read_high(int lane, int64_t first, int64_t count, uint16_t* xray_high) const;
  // Both cameras' frames of one lane, mapped read-only: frame n of camera c starts at
  // frame(c, n). One copy takes them from the page cache to where they are computed.
  struct MappedFrames {
    std::unique_ptr<MappedFile> cam[2];
    size_t frame_bytes = 0;
    const uint8_t* frame(int camera, int64_t n) const {
      return cam[camera]->data() + frame_bytes * size_t(n);
    }
  };
  MappedFrames map_frames(int lane) const;
  // Truth arrays (float32 unless stated); empty when the recording has no truth.
  std::vector<float> truth_f32(int lane, const std::string& name, size_t per_line) const;
  std::string truth_text(int lane, const std::string& name) const;
  std::string lane_dir(int lane) const;

 private:
  void read(int lane, int64_t first, int64_t count, uint8_t* cam0, uint8_t* cam1, uint16_t* xray,
            int64_t* encoder, uint16_t* xray_high) const;

  std::string dir_;
  RecordingInfo info_;
};

}  // namespace rangex
