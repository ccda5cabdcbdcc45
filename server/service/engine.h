// The server's processing core: validated lines from every lane go into one bounded queue
// (a queue per lane, taken round-robin); a worker takes them in batches (bounded by count and by
// time), runs each lane's share through its LaneProcessor, and every fillet decided is stored and
// then published. Calibration and threshold changes wait for a batch boundary at which the lane has
// no fillet in progress, so no fillet is ever measured half with one calibration and half with
// another.
//
// Threads and locks (docs/concurrency.md): ingest handlers call submit() from gRPC threads;
// one worker thread owns every LaneProcessor (the assembly); inspector threads inspect,
// store and publish the fillets they cut, each lane's in order; control RPCs and the
// watchdog read state.
// Engine locks never nest and are never held while calling out of the engine (store, hub,
// processors), but the decision recorder's:
//   mu_      admission: the queue, every lane's LaneAdmission, stopping/paused flags
//   ctl_mu_  control: lanes' configurations, pending changes, calibration ids
//   inspect_mu_  the fillets waiting for an inspector, which lanes an inspector holds
//   learn_mu_  which lane has a live learning run (its collector has a lock of its own)
//   the recorder's (decision_recorder.h) storing and publishing decisions; held while
//            calling the store and the hub (neither calls back into the engine)
//   leaf locks inside LatencyStats, rate_mu_, the recorder's error lock
// Counters are atomics, so statistics never wait for ingest and ingest never waits for them.
#pragma once
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "backends/stage_runner.h"
#include "core/incoming_line.h"
#include "core/plant_config.h"
#include "pipeline/lane_processor.h"
#include "pipeline/product_drift.h"
#include "plantdb/forward_status.h"
#include "plc/plc_state.h"
#include "sensors/sensor_state.h"
#include "service/decision_recorder.h"
#include "service/lane_admission.h"
#include "service/lane_queues.h"
#include "service/latency_stats.h"
#include "service/line_codes.h"
#include "service/results_hub.h"
#include "service/shift_recorder.h"
#include "service/verifications.h"
#include "store/store.h"

namespace rangex {

struct LearningSet;   // pipeline/lane_learning.h
struct KeptLearning;  // service/engine_learning.cpp

struct EngineOptions : EngineSettings {
  BackendRequest backend;  // where the line stages run (plant.backend, --backend)
  bool images = true;      // store images of rejected / not inspected fillets
  // Fault injection for tests: runs on the worker before each batch. A hook that blocks
  // stalls the worker the way a hung disk or device would.
  std::function<void()> batch_hook;
  // Each decision once committed, before it is published (the PLC's release); called on an
  // inspector under the decision recorder's lock: it must only queue.
  std::function<void(const StoredFillet&)> on_decided;
  // Lanes that another server ran before this one (plantdb/lane_handover.h): by lane, the
  // next fillet number and the encoder count up to which fillets were decided there.
  struct LaneContinuation {
    int64_t next_fillet = 0, decided_until = INT64_MIN;
  };
  std::map<int, LaneContinuation> continue_lanes;
};

struct Health {
  bool serving = true;   // the server can inspect
  bool store_ok = true;  // results and calibrations can be stored and read
  std::vector<std::string> reasons;
};

struct EngineStats {
  uint64_t received = 0, accepted = 0, processed = 0;
  uint64_t fillets = 0, rejects = 0, not_inspected = 0, lane_restarts = 0, store_errors = 0;
  // Bytes copied on the way in: by gRPC's parser out of the wire into each request's strings
  // (every line received), and each processed line's X-ray into its lane's assembly.
  uint64_t bytes_parsed = 0, bytes_xray_copied = 0;
  std::map<std::string, uint64_t> refused;  // at admission, by code
  std::map<std::string, uint64_t> dropped;  // accepted but not processed, by reason
  double lines_per_second = 0;
  int queue_depth = 0, queue_capacity = 0;
  LatencyStats::Summary queue_wait, pipeline, inspection, decision;
  LatencyStats::Summary inspection_wait;  // a cut fillet waiting for the inspector
  LatencyStats::Summary store;            // storing a decision (its images included)
  std::vector<std::pair<std::string, LatencyStats::Summary>> inspection_stages;
  Health health;
  std::vector<std::string> warnings;          // e.g. lanes that stopped being fed
  BackendInfo backend;                        // what runs the line stages now
  std::string backend_note;                   // why that one (a choice of auto, a fallback)
  StageRunnerStats batches;                   // batches, verified on the CPU, mismatches, failures
  std::optional<PlcStatus> plc;               // with a PLC (plant.yaml plc)
  std::optional<ForwarderStatus> forwarding;  // with a plant-wide database (plant.results_db)
  RecordingStatus recording;                  // the shift recording running or last ended
  int64_t open_files = -1;                    // the process's, now (-1: unknown)
  uint64_t open_files_limit = 0;              // its soft limit (0: unknown)
};

// What a stop does with the fillets still coming in: the end of a recording closes them (one
// cut off is not inspected); a server that another will follow hands them back undecided,
// their lines not durable, so that the feeders resend them to the next server.
enum class OpenFillets { kClose, kHandBack };

// How far a lane's lines are safe (StreamLinesResponse.lanes).
struct LaneProgress {
  int lane = 0;
  int64_t durable =
      INT64_MIN;  // a feeder may forget the lines up to it (a restart resumes after it)
  int64_t settled = INT64_MIN;  // the outcomes of the lines up to it are in the store
};

struct LaneState {
  LaneConfig config;  // with a pending change, what it will be
  std::string calibration_id;
  bool fed = false;          // a line accepted since start or reset
  int64_t last_encoder = 0;  // the last accepted count (when fed)
  uint64_t accepted = 0;
  int64_t idle_ms = -1;  // since the last line received (accepted or not); -1: none yet
  bool fillet_in_progress = false;
  uint64_t restarts = 0;
  std::string last_restart;
  // Since the server started: lines received (sizes checked, then refused or accepted),
  // processed, refused by code, dropped by reason; fillets decided, by decision.
  uint64_t received = 0, processed = 0, fillets = 0, rejects = 0, not_inspected = 0;
  std::map<std::string, uint64_t> refused, dropped;
  // With learned thresholds: the false-reject rate the lane's recently passed fillets imply
  // (-1: not estimated yet), over how many, and whether that is more than twice the target.
  double implied_frr = -1;
  int drift_fillets = 0;
  bool product_drift = false;
  std::optional<LaneSensors> sensors;  // a lane fed by its own sensors (plant.yaml sources)
  std::string plc;  // with a PLC: the lane's state as last written, or why the PLC is not reached
  LaneVerification verification;  // the last verification run, one running, overdue
};

class Engine {
 public:
  Engine(const PlantConfig& plant, Store& store, ResultsHub& hub, EngineOptions opt);
  ~Engine();

  struct Verdict {
    bool accepted = false;
    Refusal code = Refusal::kCount;  // when refused
    std::string message;
    int credit = 0;  // lines the queue can take now
    // The lane's durable count (INT64_MIN: none yet, or no lane): every line of the lane up
    // to it has its outcome in the store; a feeder may forget those lines.
    int64_t durable = INT64_MIN;
  };
  // Validates and queues one line; never throws for bad input (the verdict says why).
  Verdict submit(IncomingLine&& line);
  // A request that carried no line: refused and counted like any other.
  Verdict refuse_empty(uint64_t sequence);
  // Places free in the queue now.
  int free_places() const;
  // Graceful stop: refuse new lines (handed back), process every queued one, then close the
  // open fillets or hand them back. False when the worker could not finish within
  // `timeout_s` (< 0: wait as long as it takes).
  bool drain_and_stop(double timeout_s = -1, OpenFillets open = OpenFillets::kClose);
  // Every fed lane's durable and settled counts.
  std::vector<LaneProgress> progress();
  // Holds the worker (tests use it to fill the queue and see overload handled).
  void pause(bool paused);

  std::vector<LaneState> lanes();
  LaneState lane_state(int lane);
  std::string calibration_of(int lane);
  // report: the solvers' JSON report, stored with the set ("" when none); an unreadable
  // report is refused. Activation refuses a set whose report is missing or failed unless
  // `force` (audited as calibration.activate.forced with what it overrode).
  StoredCalibration upload_calibration(int lane, const std::string& id, const std::string& yaml,
                                       const std::string& who, const std::string& report = "");
  bool activate_calibration(int lane, const std::string& id, const std::string& who,
                            bool force = false);
  LaneConfig update_thresholds(int lane, std::optional<double> z, std::optional<double> area,
                               std::optional<double> floor, const std::string& who);
  // Learned inspection settings (engine_learning.cpp), versioned and audited like
  // calibrations: `yaml` is an inspection.learned section, `report` its learning's report.
  // Activation is refused when the report is missing or failed unless forced (audited as
  // learned.activate.forced); it takes over at a batch boundary like thresholds.
  StoredSetting upload_learned(int lane, const std::string& id, const std::string& yaml,
                               const std::string& report, const std::string& who);
  bool activate_learned(int lane, const std::string& id, const std::string& who,
                        bool force = false);
  std::vector<StoredSetting> learned_settings(int lane);  // lane -1: all
  // A stored learned version into a lane's inspection (its thresholds and budget, under the
  // name it is stored as).
  static void apply_learned(LaneConfig& lane, const StoredSetting& version);
  struct LearnRequest {
    int fillets = 40;       // the lane's next inspected fillets
    double target_frr = 0;  // 0: the lane's false_reject_target
    double confidence = 0.9;
    int min_fillets = 0;      // fewer clean fillets fail the learning (0: 30, or the run's)
    std::string id;           // the version's name ("" : learn-<time>)
    double timeout_s = 3600;  // give up when the fillets have not come by then
    // Other false-reject targets whose thresholds and sensitivity the report gives beside
    // the learned one's (learn_lane), each in (0, 0.5), at most 8.
    std::vector<double> tradeoff;
    // Learn again from the fillets of the lane's last live learning, stored as this version,
    // with the settings that run had (no waiting; `fillets` and `timeout_s` do not apply).
    std::string relearn_from;
    // Fillets of that run (the lane's fillet ids) an operator checked clean: kept in, never
    // flagged. Needs relearn_from.
    std::vector<int64_t> keep;
  };
  // Learns the lane's product from its next fillets as they are inspected (the lane keeps
  // running on its active settings), measures the sensitivity with test pieces, and stores
  // the result as a new version with its report (not activated). Blocks until done; throws
  // Error when the fillets do not come within the timeout or the server stops.
  StoredSetting learn_product(int lane, const LearnRequest& req, const std::string& who);
  // The lane's next line starts it afresh whatever its count (an encoder reset); its open
  // fillets end as not inspected.
  LaneState reset_lane(int lane, const std::string& who, const std::string& reason);
  // A lane's sensor dropped off: its open fillets end now as not inspected for `why` (audited
  // as lane.sensor_lost). The lane's counts go on where the sensors take them up again.
  void sensor_lost(int lane, const std::string& why);
  // Where lane states, statistics and health read the sensors' states from (the server's
  // sensor ingest); none: every lane is fed over gRPC.
  void set_sensor_states(std::function<std::vector<LaneSensors>()> states);
  // Where statistics, lane states and warnings read the PLC link's status from.
  void set_plc_status(std::function<PlcStatus()> status);
  // Where statistics and warnings read the forwarding to the plant-wide database from.
  void set_forward_status(std::function<ForwarderStatus()> status);
  // The forwarding's status alone (none without a plant-wide database), without the rest of
  // the statistics.
  std::optional<ForwarderStatus> forwarding();
  // A shift recorded on the server (shift_recorder.h): the lanes' accepted lines written as
  // recordings in <data>/recordings/NAME. start refuses what would not fit the disk.
  RecordingStatus start_recording(const RecordingRequest& req, const std::string& who);
  RecordingStatus stop_recording(const std::string& who);
  // A verification run on a lane (verifications.h): its next fillets must show the piece.
  LaneState start_verification(const VerificationRequest& req, const std::string& who);
  EngineStats stats();
  Health health();
  const PlantConfig& plant() const { return plant_; }
  const EngineOptions& options() const { return opt_; }
  BackendInfo backend() const { return runner_->running(); }
  // Drawn at start: tells a reconnecting feeder whether this server had its lines.
  uint64_t epoch() const { return epoch_; }
  std::string backend_note() const { return runner_->note(); }

 private:
  struct Lane {
    Lane(const LaneConfig& c, const EngineOptions& o, size_t slot);
    const int id;
    const size_t slot;                          // its place in lanes_ and in the queues
    const int width, height, pixels, energies;  // fixed for the server's life
    // Admission (mu_):
    LaneAdmission admission;
    std::string end_now;  // mu_: the worker ends the open fillets for this reason (a sensor lost)
    std::string admit_calibration;  // lines naming another calibration are refused
    uint64_t accepted = 0;
    int64_t last_line_ns = 0;  // the last line received for the lane, accepted or refused
    // Lines handed back while the store could not write: later counts are refused the same
    // way until this one comes again (or for kHandBackHoldS after the last such refusal),
    // so that the resent lines still enter in count order.
    int64_t handback_from = INT64_MAX;
    int64_t handback_ns = 0;
    // Control (ctl_mu_):
    LaneConfig config;
    std::string calibration_id;
    std::optional<LaneConfig> pending;
    std::string pending_id;
    std::string last_restart;
    // Worker thread only:
    std::unique_ptr<LaneProcessor> proc;
    std::string running_calibration;
    std::deque<std::pair<int64_t, int64_t>> arrivals;  // (encoder, steady ns) of recent lines
    int64_t last_push_ns = 0;
    int64_t assembly_restarts = 0;
    std::vector<uint16_t> xray;  // one line (low and high: a dual lane), aligned for the assembly
    // Read anywhere:
    std::atomic<bool> in_progress{false};
    std::atomic<uint64_t> restarts{0};
    std::atomic<uint64_t> received{0}, processed{0}, fillets{0}, rejects{0}, not_inspected{0};
    std::array<std::atomic<uint64_t>, kRefusals> refused{};
    std::array<std::atomic<uint64_t>, kDropReasons> dropped{};
    // Inspection (inspect_mu_): an inspector holds one of the lane's fillets.
    bool inspecting = false;
    // The inspector holding the lane: its passed fillets' extremes against the learned model;
    // what they imply, for anyone to read.
    DriftTracker drift;
    // A live learning run collecting the lane's next fillets (learn_mu): their images when
    // cut, their extremes when decided.
    std::shared_ptr<struct ProductCollector> collector;
    // The last live learning run's fillets and settings (learn_mu), for a re-learning that
    // keeps fillets an operator checked clean: the last run only, in memory only.
    std::shared_ptr<KeptLearning> last_learning;
    std::atomic<double> implied_frr{-1};
    std::atomic<int> drift_fillets{0};
    std::atomic<bool> product_drift{false};
    // Durability (engine_progress.cpp): the count up to which the lane's lines are settled in
    // the assembly (worker), the same for each fillet cut and not yet stored (pending_mu),
    // both less the lines needed to rebuild what follows; what was last made durable.
    std::atomic<int64_t> assembly_durable{INT64_MIN};
    std::mutex pending_mu;
    std::multimap<int64_t, int64_t> pending_fillets;  // first count -> its durable bound
    std::atomic<int64_t> durable_saved{INT64_MIN};
    // The same without the lines kept for a rebuild: outcomes stored up to it (worker; less
    // the fillets pending in pending_fillets when read).
    std::atomic<int64_t> assembly_settled{INT64_MIN};
    int64_t last_pushed = INT64_MIN;  // worker: the last count given to the assembly
    // Worker: after a restart of the server, fillets starting at or before this count were
    // decided before it (their lines come again from the resuming feeder): not again.
    int64_t decided_until = INT64_MIN;
  };
  using Queued = QueuedLine;
  struct InspectJob {  // a fillet the worker cut, for the inspector
    Lane* lane;
    FilletImage image;
    InspectionParams params;
    std::string calibration;  // the one the lane ran when it saw the fillet
    int64_t last_arrival_ns;  // arrival of the fillet's last line (0: unknown)
    int64_t queued_ns;
  };
  Verdict refuse(Lane* l, Refusal code, std::string message, size_t queued);  // l: when known
  void worker();
  void process(std::vector<Queued>& batch);
  bool changes_waiting(const std::vector<Queued>& batch);
  void route(std::vector<Queued>& lines, const LineResults& r);
  void lose(std::vector<Queued>& lines, const std::string& why);
  void recover(Lane& l, const std::string& why);
  void apply_pending(Lane& l);
  void restart_lane(Lane& l, const std::string& reason);
  void note_assembly_restarts(Lane& l);
  void close_idle_lanes();
  void on_image(Lane& l, FilletImage&& img);                   // worker
  void inspector();                                            // an inspector thread
  void on_fillet(const InspectJob& job, InspectedFillet&& f);  // inspector
  // Durable counts (engine_progress.cpp).
  void resume_from_store();                             // constructor
  int64_t durable_margin(const Lane& l) const;          // lines to rebuild from
  void note_assembly(Lane& l);                          // worker, after lines or a restart
  bool fillet_cut(Lane& l, const FilletImage& img);     // worker; false: decided before
  void fillet_stored(int lane, int64_t first_encoder);  // inspector, once committed
  void save_progress();                                 // the progress thread
  void progress_loop();
  Lane& lane(int id);
  // A passed fillet's extremes into the lane's drift tracker (the inspector holding the lane).
  void track_drift(Lane& l, const LearnedDetection& learned,
                   const std::vector<BandExtreme>& extremes);
  // Live learning (engine_learning.cpp): the lane's collector, if any (learn_mu_).
  std::shared_ptr<ProductCollector> collector_of(Lane& l);
  void collect_image(Lane& l, const FilletImage& img);
  void collect_result(Lane& l, const FilletResult& r);
  // Waits for the lane's next req.fillets inspected fillets (a live learning run).
  LearningSet collect_fillets(Lane& l, int id, const std::string& vid, const LearnRequest& req,
                              const std::string& who);
  std::mutex learn_mu_;

  PlantConfig plant_;
  Store& store_;
  EngineOptions opt_;
  DecisionRecorder recorder_;  // store, images and hub: the way back of every decision
  std::vector<std::unique_ptr<Lane>> lanes_;
  std::unordered_map<int, Lane*> by_id_;
  std::unique_ptr<StageRunner> runner_;  // worker only, but for its read-only accessors

  std::mutex mu_;
  std::condition_variable cv_;
  mutable std::mutex sensors_mu_;  // leaf: the provider below
  std::function<std::vector<LaneSensors>()> sensor_states_;
  std::function<PlcStatus()> plc_status_;            // sensors_mu_
  std::function<ForwarderStatus()> forward_status_;  // sensors_mu_
  std::unique_ptr<ShiftRecorder> shift_;
  std::unique_ptr<Verifications> verifications_;  // before the recorder calls into it
  LaneQueues queue_;
  bool stopping_ = false, paused_ = false;
  OpenFillets at_stop_ = OpenFillets::kClose;  // mu_; read by the worker once it stops
  std::atomic<size_t> queued_{0};
  std::atomic<bool> stopping_flag_{false};

  std::mutex ctl_mu_;

  std::thread worker_;
  // Fillets cut by the worker, inspected on the inspector threads (each lane's in order),
  // so that a decision does not wait behind the lines of other lanes (bounded: a full queue
  // holds the worker).
  std::vector<std::thread> inspectors_;
  std::mutex inspect_mu_;
  std::condition_variable inspect_cv_, inspect_room_;
  std::deque<InspectJob> inspect_queue_;
  bool inspect_stop_ = false;
  static constexpr size_t kMaxInspectQueue = 32;
  std::mutex done_mu_;
  std::condition_variable done_cv_;
  bool done_ = false;
  std::atomic<int64_t> batch_started_ns_{0};

  uint64_t epoch_ = 0;
  std::thread progress_;
  std::mutex progress_mu_;
  std::condition_variable progress_cv_;
  bool progress_stop_ = false;
  bool progress_failed_ = false;  // progress thread only

  std::atomic<uint64_t> received_{0}, accepted_{0}, processed_{0};
  std::atomic<uint64_t> bytes_parsed_{0}, bytes_xray_copied_{0};
  std::atomic<uint64_t> fillets_{0}, rejects_{0}, not_inspected_{0};
  std::array<std::atomic<uint64_t>, kRefusals> refused_{};
  std::array<std::atomic<uint64_t>, kDropReasons> dropped_{};

  std::mutex rate_mu_;
  std::deque<std::pair<int64_t, uint64_t>> rate_;  // (steady ns, processed) samples
  LatencyStats queue_wait_, pipeline_, inspection_, inspection_wait_;
  LatencyStats inspection_stage_[kStages];
};

}  // namespace rangex
