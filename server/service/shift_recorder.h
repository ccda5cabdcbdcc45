// A shift recorded on the server: the lines rangexd accepts for the chosen lanes written as
// recordings (one per lane, <data>/recordings/NAME/laneL, the format `rangexctl process`
// replays), so that an engineer can replay a shift with a new calibration or new thresholds.
// A recording is refused before it starts when its estimate does not fit the disk (the free
// space less the store's reserve), and ends when its minutes are up, when it has written the
// space it was given, or when asked. Ingest never waits for it: lines are copied into a
// bounded queue that a writer thread empties; a line that finds the queue full is left out
// of the recording and counted. Start and end are audited.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/incoming_line.h"
#include "core/plant_config.h"

namespace rangex {

class RecordingWriter;

struct RecordingRequest {
  std::vector<int> lanes;  // empty: every lane
  double minutes = 10;
  std::string name;  // "" : shift-<UTC time>
};

struct RecordingStatus {
  bool active = false;
  std::string name, dir;
  std::vector<int> lanes;
  double minutes = 0;
  int64_t started_unix_ns = 0;
  uint64_t lines = 0;           // written
  uint64_t left_out = 0;        // accepted while the queue was full: not in the recording
  uint64_t bytes = 0;           // written
  uint64_t budget_bytes = 0;    // the most it may write
  uint64_t estimate_bytes = 0;  // what its minutes would take at the lanes' rate at start
  std::string ended;            // why it ended ("" while active or before any)
};

class ShiftRecorder {
 public:
  using Audit = std::function<void(const std::string& who, const std::string& what,
                                   const std::string& detail)>;
  ShiftRecorder(const PlantConfig& plant, std::string data_dir, double reserve_mb, Audit audit);
  ~ShiftRecorder();

  // `lines_per_s`: each lane's rate now (for the estimate). Throws InvalidArgument for bad
  // lanes or minutes, FailedPrecondition when one is running or it does not fit the disk.
  RecordingStatus start(const RecordingRequest& req, double lines_per_s, const std::string& who);
  RecordingStatus stop(const std::string& who, const std::string& why = "stopped");
  RecordingStatus status() const;
  // The fast path for ingest: whether lines of `lane` are wanted now.
  bool wants(int lane) const;
  // A line's bytes, copied (before admission, outside its lock) for the recording.
  struct Line {
    int lane = 0;
    int64_t encoder = 0;
    std::string cam0, cam1, xray;
    std::string xray_high;  // a dual-energy lane's
  };
  static Line copy(const IncomingLine& in);
  // An accepted line for the recording (left out, counted, when the queue is full).
  void offer(Line&& line);

 private:
  void run();
  void end(const std::string& who, const std::string& why);  // the writer, under mu_

  const PlantConfig plant_;
  const std::string root_;
  const double reserve_mb_;
  Audit audit_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  RecordingStatus status_;
  std::map<int, std::unique_ptr<RecordingWriter>> writers_;
  std::deque<Line> queue_;
  std::atomic<uint64_t> lanes_mask_{0};  // lanes 0..63 being recorded
  int64_t deadline_ns_ = 0;              // steady
  bool stop_thread_ = false;
  std::string stop_who_, stop_why_;  // a stop asked of the writer
  std::thread thread_;
};

}  // namespace rangex
