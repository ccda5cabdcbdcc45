// The line stages of the server: batches of queued lines from any mix of lanes go to the
// selected backend as one batch each (frames copied once, into the backend's staging), with
// up to two in flight on a device so that one uploads while the other computes. Finished
// batches come back in order through the sink, with each line's results.
//
// Lanes that share frame size, fusion grid and detector pixels share a backend (a plant
// usually has one such group). Beside a device backend, the CPU reference is kept with the
// same tables: a fraction of batches is recomputed on it and compared stage by stage (a
// mismatch is counted, logged with the first differing item, and the batch goes on with the
// CPU's results), and when the device fails (a failed dispatch, a lost device, no memory)
// the batches in flight are recomputed on it and the server stays on the CPU: no line lost.
//
// The server's engine and the offline runs (offline/line_path.h) both go through it.
//
// Worker thread only, except the read-only accessors marked as such.
#pragma once
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "backends/backend.h"
#include "backends/registry.h"
#include "core/incoming_line.h"
#include "pipeline/lane_processor.h"

namespace rangex {

struct StageRunnerOptions {
  BackendRequest backend;
  double verify_fraction = 0.01;  // of batches on a device, recomputed on the CPU
  // A backend that cannot start: run on the CPU with a note (a server keeps inspecting), or
  // throw (a tool asked for that backend).
  bool fall_back = true;
};

struct StageRunnerStats {
  uint64_t batches = 0, verified = 0, mismatches = 0, failures = 0;
  uint64_t bytes_staged = 0;  // frame bytes copied into backends' staging
};

class StageRunner {
 public:
  // The lines of one finished batch and their results (line k is item k of `results`, the
  // fusion counts are the batch's), and the milliseconds from its launch to its results.
  using Sink =
      std::function<void(std::vector<QueuedLine>& lines, const LineResults& results, double ms)>;
  // Lines no backend could compute (only if the CPU itself fails): they are lost, with why.
  using Lost = std::function<void(std::vector<QueuedLine>& lines, const std::string& why)>;

  StageRunner(const std::vector<LaneConfig>& lanes, StageRunnerOptions opt, Sink sink, Lost lost);
  ~StageRunner();

  // Takes a batch; may finish older batches first (at most two in flight per backend).
  void launch(std::vector<QueuedLine>&& lines);
  void finish_all();
  bool busy() const { return !inflight_.empty(); }
  // A lane's new configuration, in every backend of its group; finishes what is in flight.
  void update_lane(int lane_id, const LaneConfig& lane);

  // Any thread:
  BackendInfo running() const;  // what computes now
  std::string note() const;     // why it was chosen, or why it fell back
  StageRunnerStats stats() const;

 private:
  struct Group {
    std::vector<int> lane_ids;  // slot order
    size_t frame_bytes = 0, pixels = 0;
    std::unique_ptr<Backend> cpu;     // the reference: verification, fallback, or the backend
    std::unique_ptr<Backend> device;  // the selected backend unless it is the reference
    Backend* active = nullptr;
    std::vector<std::unique_ptr<Backend>> failed;  // kept: their slots may still be in flight
  };
  struct InFlight {
    int group = 0;
    Backend* backend = nullptr;
    LineBatchSlot* slot = nullptr;
    std::vector<QueuedLine> lines;
    std::chrono::steady_clock::time_point launched;
  };

  // The lines' frames into `b`'s staging (their one copy) and their lane slots.
  LineBatchSlot& fill(Group& g, Backend& b, const std::vector<QueuedLine>& lines);
  void submit(Group& g, InFlight& f);
  void finish_oldest();
  bool compute_on_cpu(Group& g, InFlight& f, LineResults& out);
  void verify(Group& g, InFlight& f, LineResults& r);
  void fail_over(const std::string& why);
  bool verify_now();
  size_t in_flight(int group) const;

  StageRunnerOptions opt_;
  Sink sink_;
  Lost lost_;
  std::vector<Group> groups_;
  std::unordered_map<int, std::pair<int, int>> where_;  // lane id -> (group, slot)
  std::deque<InFlight> inflight_;
  LineResults results_, reference_;
  double verify_credit_ = 1;  // the first batch on a device is always verified

  std::atomic<uint64_t> batches_{0}, verified_{0}, mismatches_{0}, failures_{0};
  std::atomic<uint64_t> bytes_staged_{0};
  mutable std::mutex info_mu_;
  BackendInfo running_;
  std::string note_;
};

// Line k of a finished batch of `batch_lines` into its lane's processor, as the line path
// routes it: its X-ray line copied out of the received bytes into `xray` (aligned, the
// lane's detector pixels times its energies: a dual-energy lane's high line follows the
// low one), its thickness line marked blind where no camera saw the stripe.
void push_line_results(LaneProcessor& proc, const QueuedLine& line, const LineResults& results,
                       size_t k, size_t batch_lines, std::vector<uint16_t>& xray);

}  // namespace rangex
