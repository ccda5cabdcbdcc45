// Positive release to the line's PLC. Every decided fillet is queued; a writer thread sends
// each into the PLC's ring of holding registers (release_registers.h) in order, writes a
// heartbeat, and each lane's PackML state when it changes. A clean fillet is released only
// while the belt has not yet carried it to within margin_mm of the gate: the lane's newest
// encoder count against the fillet's first X-ray line plus the reject station's distance. A
// pass decided later is sent as late (the PLC diverts it), counted and audited; one still
// queued at its deadline because the PLC cannot be reached, or refuses the ring's registers,
// is unreleased, counted and audited. Nothing is ever assumed released.
//
// The PLC is connected once it answers a write on a connection, so a PLC that takes the TCP
// connection and answers nothing is one loss, retried with a growing backoff, not a loss and
// a reconnect each round. A refusal (a Modbus exception: its program does not map a register)
// is an answer: the connection stays, the refusal is named in the status, audited when it
// starts and when it ends, and the refused registers are tried again each second.
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

#include "core/plant_config.h"
#include "plc/plc_state.h"
#include "plc/release_registers.h"

namespace rangex {

// A lane as the writer sees it: where its belt is (the newest line's count) and its state.
struct PlcLaneView {
  int lane = 0;
  bool has_count = false;
  int64_t belt_count = 0;
  PackMl state = PackMl::kIdle;
  StateReason reason = StateReason::kNotFed;
};

struct PlcHooks {
  std::function<std::vector<PlcLaneView>()> lanes;
  // An audited event: "release.late", "release.unreleased", "plc.lost", "plc.connected".
  std::function<void(const std::string& what, const std::string& detail)> audit;
};

class PlcRelease {
 public:
  PlcRelease(const PlantConfig& plant, PlcHooks hooks);
  ~PlcRelease();
  void start();  // the writer thread (after the hooks can answer)
  // A decision, once committed (any thread; only queues).
  void decided(const Release& r);
  // Waits until everything queued is sent, the PLC is lost, or `timeout_s` passes.
  void flush(double timeout_s);
  // Writes Stopped to every lane it can reach, then stops the writer.
  void stop();
  PlcStatus status() const;
  // The first X-ray line count at which a fillet starting at `first_encoder` on `lane` can no
  // longer be released.
  int64_t deadline(int lane, int64_t first_encoder) const;

 private:
  struct Queued {
    Release r;
    int64_t queued_ns = 0;
  };
  void run();
  void connect_if_due();
  // The first `count` queued releases, in order, judged against `lanes` (read after they
  // were queued).
  void send_due(const std::vector<PlcLaneView>& lanes, size_t count);
  // Of the first `count` queued, the passes past their deadline, taken out and counted
  // unreleased (the PLC cannot be written); how many.
  size_t unreleased_at_deadline(const std::map<int, PlcLaneView>& views, size_t count);
  void heartbeat_and_states(const std::vector<PlcLaneView>& lanes);
  void lost(const std::string& why);
  // What the PLC's program maps for rangex, each refused or not on its own.
  enum class Area { kHeartbeat, kLaneStates, kRing, kRingHead };
  // Writes registers of `area`; false when the PLC refuses them, or refused them less than a
  // second ago. A failure of the connection throws.
  bool write(Area area, int first, const uint16_t* values, int n);
  bool refused(Area area) const;
  void answered();       // the PLC answered a write on this connection
  void show_refusals();  // status_.refused from the areas refused (under mu_)

  const PlcConfig cfg_;
  std::map<int, int64_t> deadline_lines_;  // by lane: the gate's distance less the margin
  std::map<int, double> step_mm_;
  PlcHooks hooks_;
  std::unique_ptr<class ModbusLink> link_;

  mutable std::mutex mu_;  // queue_, status_
  std::condition_variable wake_;
  std::deque<Queued> queue_;
  PlcStatus status_;
  bool stop_ = false;
  bool woken_ = false;  // a release decided since the writer's last round
  std::thread thread_;

  // The writer's own.
  double backoff_s_ = 0.2;
  bool answered_ = false;  // a write answered on this connection
  bool ever_connected_ = false;
  struct Refusal {
    int64_t retry_ns = 0;
    std::string why;
  };
  std::map<Area, Refusal> refusals_;  // the areas the PLC refuses now
  int64_t next_connect_ns_ = 0, next_beat_ns_ = 0;
  uint16_t beat_ = 0;
  std::map<int, std::pair<PackMl, StateReason>> written_;  // lane states the PLC has
  std::map<int, std::pair<int64_t, int64_t>> belt_;        // lane: count and when (steady ns)
};

}  // namespace rangex
