// Stage 4, per-lane assembly: X-ray lines and thickness lines are paired by encoder count
// (the X-ray plane is delay_lines behind the laser plane), stacked, and cut into fillets:
// connected regions of thickness above the floor. A run of lines with fillet in it is
// closed by gap_lines empty lines (or max_segment_lines); its regions are labelled, and each
// region big enough is one fillet (fillets that touch are one region and are inspected
// together). Lines that never came, or were dropped, are recorded; every fillet they touch
// is failed safe by the inspection.
//
// Gaps cost work in proportion to the fillets they touch, not to their length in counts:
// at most a segment's worth of missing rows is walked, the rest is skipped. A jump beyond
// encoder_horizon_lines, or an explicit restart (an encoder reset, a lane that stopped
// being fed), ends the open fillets as not inspected and starts afresh.
#pragma once
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/fillet_image.h"

namespace rangex {

struct Component;  // pipeline/connected_components.h

struct AssemblyStats {
  int64_t lines = 0;          // X-ray lines taken in, missing ones included
  int64_t missing_lines = 0;  // lines marked missing
  int64_t fillets = 0;
  int64_t debris = 0;        // regions below the minimum fillet area
  int64_t restarts = 0;      // explicit restarts and jumps beyond the horizon
  int64_t out_of_order = 0;  // lines at or behind the last one, ignored
};

class LaneAssembler {
 public:
  using Sink = std::function<void(FilletImage&&)>;
  LaneAssembler(const LaneConfig& lane, Sink sink);

  // One line: the camera line's thickness (detector pixels, NaN where not measured), which
  // the X-ray sees delay_lines later, and the X-ray line of the same count. Counts must
  // increase; counts skipped are missing lines.
  // xray_high: a dual-energy lane's high-energy line (null for a lane of one energy).
  void push(int64_t encoder, const float* thickness, const uint16_t* xray,
            const uint16_t* xray_high = nullptr);
  // A line that was dropped (both thickness and X-ray are unusable).
  void push_missing(int64_t encoder);
  // Ends the open fillets as not inspected with `reason` (fillets already complete are
  // inspected as usual) and starts afresh: the next line may have any count.
  void restart(const std::string& reason);
  // Closes the open run (end of a recording, or shutdown) and emits its fillets; one still
  // coming in is not inspected.
  void flush();

  const AssemblyStats& stats() const { return stats_; }
  const std::string& last_restart() const { return last_restart_; }
  // The number the next fillet gets (a server continues its lanes' numbering after a restart).
  void set_next_id(int64_t id) { next_id_ = id; }
  int64_t next_id() const { return next_id_; }
  // No fillet in progress and no waiting thickness line with fillet in it: a new
  // configuration can take over without any fillet seeing two.
  bool quiet() const;
  // The first X-ray count whose row can still become part of a fillet: the open segment's
  // first row, else the next count to come (INT64_MIN before the first line).
  int64_t pending_from() const {
    return open_ && !segment_.empty() ? segment_.front().encoder : next_encoder_;
  }
  void set_config(const LaneConfig& lane) { lane_ = lane; }

 private:
  struct Row {
    int64_t encoder;
    int64_t line;
    std::vector<uint16_t> xray;       // empty when the X-ray line is missing
    std::vector<uint16_t> xray_high;  // a dual-energy lane's high-energy line
    std::vector<float> thickness;     // empty when no camera line covers this slice
    bool missing;
    bool occupied;
  };
  // Accounts for the counts between the last line and `encoder`; false: out of order.
  bool advance(int64_t encoder);
  void add_missing(int64_t encoder);
  void add_row(Row&& row);
  bool occupied(const std::vector<float>& t) const;
  void close_segment();
  std::vector<uint8_t> segment_mask() const;
  FilletImage cut_fillet(const Component& c, const std::vector<int>& labels, int missing,
                         bool interrupted);
  void close_all(const std::string& reason);
  void start_line(int64_t encoder);

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
  double open_beam_ = 0;     // running estimate of the bare-belt X-ray level
  std::string interrupted_;  // while closing for a restart: why
  std::string last_restart_;
  AssemblyStats stats_;
};

}  // namespace rangex
