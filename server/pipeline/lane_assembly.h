// Stage 4, per-lane assembly: X-ray lines and thickness lines are paired by encoder count
// (the X-ray plane is delay_lines behind the laser plane), stacked, and cut into fillets:
// connected regions of thickness above the floor. A run of lines with fillet in it is
// closed by gap_lines empty lines (or max_segment_lines); its regions are labelled, and each
// region big enough is one fillet (fillets that touch are one region and are inspected
// together). Lines that never came, or were dropped, are recorded; every fillet they touch
// is failed safe by the inspection.
#pragma once
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/fillet_image.h"

namespace rangex {

struct AssemblyStats {
  int64_t lines = 0;          // X-ray lines taken in
  int64_t missing_lines = 0;  // lines marked missing
  int64_t fillets = 0;
  int64_t debris = 0;  // regions below the minimum fillet area
};

class LaneAssembler {
 public:
  using Sink = std::function<void(FilletImage&&)>;
  LaneAssembler(const LaneConfig& lane, Sink sink);

  // One camera line: its thickness line is what the X-ray sees delay_lines later.
  // thickness: detector pixels, NaN where not measured.
  void push_thickness(int64_t encoder, const float* thickness);
  // One X-ray line. Lines must come with increasing encoder counts; a jump is recorded as
  // missing lines.
  void push_xray(int64_t encoder, const uint16_t* xray);
  // A line that was dropped (both thickness and X-ray are unusable).
  void push_missing(int64_t encoder);
  // Closes the open run (end of a recording, or shutdown) and emits its fillets.
  void flush();

  const AssemblyStats& stats() const { return stats_; }
  // No fillet in progress and no waiting thickness line with fillet in it: a new
  // configuration can take over without any fillet seeing two.
  bool quiet() const;
  void set_config(const LaneConfig& lane) { lane_ = lane; }

 private:
  struct Row {
    int64_t encoder;
    int64_t line;
    std::vector<uint16_t> xray;
    std::vector<float> thickness;
    bool missing;
    bool occupied;
  };
  void add_row(Row&& row);
  void close_segment();

  LaneConfig lane_;
  Sink sink_;
  int pixels_;
  std::map<int64_t, std::vector<float>> thickness_;  // by camera encoder, awaiting its X-ray line
  std::deque<Row> segment_;
  int empty_run_ = 0;
  bool open_ = false;  // the segment holds fillet rows
  int64_t next_encoder_ = INT64_MIN;
  int64_t first_encoder_ = INT64_MIN;
  int64_t next_id_ = 0;
  double open_beam_ = 0;  // running estimate of the bare-belt X-ray level
  AssemblyStats stats_;
};

}  // namespace rangex
