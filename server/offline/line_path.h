// The server's line path for offline runs (replay, simulated plants, benches): blocks of lines
// from any lanes go through a StageRunner, the engine's way of running the line stages on the
// backend asked for, and each line's results into its lane's LaneProcessor through the same
// push_line_results the engine routes with. A block is finished before run() returns, so a
// caller can compare each line with its truth while it still holds it.
#pragma once
#include <functional>
#include <unordered_map>
#include <vector>

#include "backends/stage_runner.h"

namespace rangex {

class LinePath {
 public:
  // Sees every finished block before its lines go to the lane processors (line k of `lines`
  // is item k of `results`): what a caller keeps beside the inspection (stripe rows, truth).
  using Observer = std::function<void(const std::vector<QueuedLine>& lines, const LineResults& r)>;

  // Throws when the backend asked for cannot start: a tool that names one means it. Lines are
  // not verified against the CPU here (the backend tests do that); a failing device still
  // hands its batches to the CPU, as in the server.
  explicit LinePath(const std::vector<LaneConfig>& lanes, const BackendRequest& backend);

  // The processor that takes lane `lane_id`'s lines (the caller owns it; it outlives the runs).
  void attach(int lane_id, LaneProcessor* proc);

  // One block through the stages and into the processors. The lines come back in `lines`,
  // their buffers kept, so that the next block can be written into them.
  void run(std::vector<QueuedLine>& lines, const Observer& observe = {});

  BackendInfo backend() const { return runner_.running(); }
  // Fusion counts of a lane's blocks (a block counts for the lane of its first line).
  FusionStats fusion(int lane_id) const;
  double stage_seconds() const { return stage_s_; }  // launch to results, summed

 private:
  struct Lane {
    LaneProcessor* proc = nullptr;
    std::vector<uint16_t> xray;  // one line, aligned for the assembly
    FusionStats fusion;
  };
  void finished(std::vector<QueuedLine>& lines, const LineResults& r, double ms);

  const Observer* observe_ = nullptr;  // the current run's
  std::unordered_map<int, Lane> lanes_;
  StageRunner runner_;
  std::vector<QueuedLine> done_;
  double stage_s_ = 0;
};

// A block's lines ready to be written: `count` lines of lane `lane_id`, frames of
// `frame_bytes` and X-ray lines of `pixels` detector pixels, buffers reused when sized.
void shape_block(std::vector<QueuedLine>& lines, int count, int lane_id, size_t frame_bytes,
                 int pixels);

}  // namespace rangex
