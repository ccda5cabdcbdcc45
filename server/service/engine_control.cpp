// Lane control: calibration sets and threshold changes, versioned, gated by their reports,
// audited, and taken over by a lane at a batch boundary with no fillet in progress; lane
// state for the control plane and encoder resets.
#include "core/calibration_report.h"
#include "core/error.h"
#include "core/size_limits.h"
#include "service/engine.h"
#include "service/steady_ns.h"

namespace rangex {

std::vector<LaneState> Engine::lanes() {
  std::vector<LaneState> out;
  for (auto& l : lanes_) out.push_back(lane_state(l->id));
  return out;
}

void Engine::set_sensor_states(std::function<std::vector<LaneSensors>()> states) {
  std::lock_guard<std::mutex> lock(sensors_mu_);
  sensor_states_ = std::move(states);
}

RecordingStatus Engine::start_recording(const RecordingRequest& req, const std::string& who) {
  // Each lane's rate now, for the estimate: the plant's lines/s over the lanes fed.
  const EngineStats s = stats();
  int fed = 0;
  for (const LaneState& l : lanes()) fed += l.fed;
  return shift_->start(req, fed ? s.lines_per_second / fed : 0, who);
}

LaneState Engine::start_verification(const VerificationRequest& req, const std::string& who) {
  verifications_->start(req, who);
  return lane_state(req.lane);
}

RecordingStatus Engine::stop_recording(const std::string& who) {
  return shift_->stop(who, "stopped by " + who);
}

void Engine::set_plc_status(std::function<PlcStatus()> status) {
  std::lock_guard<std::mutex> lock(sensors_mu_);
  plc_status_ = std::move(status);
}

void Engine::set_forward_status(std::function<ForwarderStatus()> status) {
  std::lock_guard<std::mutex> lock(sensors_mu_);
  forward_status_ = std::move(status);
}

std::optional<ForwarderStatus> Engine::forwarding() {
  std::lock_guard<std::mutex> lock(sensors_mu_);
  if (!forward_status_) return std::nullopt;
  return forward_status_();
}

LaneState Engine::lane_state(int id) {
  Lane& l = lane(id);
  LaneState s;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    s.config = l.pending ? *l.pending : l.config;
    s.calibration_id = l.calibration_id;
    s.last_restart = l.last_restart;
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    s.fed = l.admission.fed();
    s.last_encoder = l.admission.last();
    s.accepted = l.accepted;
    if (l.last_line_ns) s.idle_ms = (steady_ns() - l.last_line_ns) / 1'000'000;
  }
  s.fillet_in_progress = l.in_progress;
  s.restarts = l.restarts;
  s.received = l.received;
  s.processed = l.processed;
  s.fillets = l.fillets;
  s.rejects = l.rejects;
  s.not_inspected = l.not_inspected;
  s.implied_frr = l.implied_frr;
  s.drift_fillets = l.drift_fillets;
  s.product_drift = l.product_drift;
  for (size_t i = 0; i < kRefusals; ++i)
    if (const uint64_t n = l.refused[i]) s.refused[std::string(refusal_name(Refusal(i)))] = n;
  for (size_t i = 0; i < kDropReasons; ++i)
    if (const uint64_t n = l.dropped[i]) s.dropped[std::string(drop_name(DropReason(i)))] = n;
  s.verification = verifications_->lane(id);
  {
    std::lock_guard<std::mutex> lock(sensors_mu_);
    if (sensor_states_)
      for (LaneSensors& ls : sensor_states_())
        if (ls.lane == id) s.sensors = std::move(ls);
    if (plc_status_) {
      const PlcStatus p = plc_status_();
      const auto it = p.lane_states.find(id);
      s.plc = !p.connected         ? "unreachable: " + p.error
              : !p.refused.empty() ? "refusing: " + p.refused
                                   : (it == p.lane_states.end() ? "connected" : it->second);
    }
  }
  return s;
}

std::string Engine::calibration_of(int id) {
  Lane& l = lane(id);
  std::lock_guard<std::mutex> lock(ctl_mu_);
  return l.calibration_id;
}

StoredCalibration Engine::upload_calibration(int id, const std::string& cid,
                                             const std::string& yaml, const std::string& who,
                                             const std::string& report) {
  Lane& l = lane(id);
  check_name("a calibration's id", cid);
  check_size("calibration '" + cid + "'", yaml.size(), kMaxCalibrationBytes);
  check_size("calibration '" + cid + "' report", report.size(), kMaxReportBytes);
  LaneConfig base;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    base = l.config;
  }
  // Parse now: a malformed or non-finite calibration is refused at upload, naming the key.
  const LaneConfig parsed = apply_lane_calibration(base, yaml, "calibration '" + cid + "'");
  if (parsed.xray.pixels != l.pixels || parsed.frame_width != l.width ||
      parsed.frame_height != l.height)
    fail("calibration '", cid, "' changes the sensor sizes of lane ", id, "; that needs a restart");
  const ReportStatus rs = check_calibration_report(report);
  if (rs.present && !rs.passed && rs.why.rfind("the report cannot be read", 0) == 0)
    fail("calibration '", cid, "': ", rs.why);
  StoredCalibration c{id, cid, yaml, now_ns(), false, report};
  store_.add_calibration(c);
  store_.audit(who, "calibration.upload",
               "lane " + std::to_string(id) + " id " + cid + " report " +
                   (rs.passed    ? "passed"
                    : rs.present ? "failed"
                                 : "missing"));
  return c;
}

bool Engine::activate_calibration(int id, const std::string& cid, const std::string& who,
                                  bool force) {
  Lane& l = lane(id);
  const auto c = store_.calibration(id, cid);
  if (!c) fail_not_found("lane ", id, " has no calibration '", cid, "'");
  const ReportStatus rs = check_calibration_report(c->report);
  if (!rs.passed && !force)
    throw FailedPrecondition(join("calibration '", cid, "' of lane ", id, " is not activated: ",
                                  rs.why, " (force the activation to override; it is audited)"));
  LaneConfig base = plant_.lane(id);
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    base.inspection = l.config.inspection;  // thresholds stay as they are
  }
  LaneConfig next = apply_lane_calibration(base, c->yaml, "calibration " + cid);
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    l.pending = std::move(next);
    l.pending_id = cid;
  }
  store_.set_active_calibration(id, cid);
  if (rs.passed)
    store_.audit(who, "calibration.activate", "lane " + std::to_string(id) + " id " + cid);
  else
    store_.audit(who, "calibration.activate.forced",
                 "lane " + std::to_string(id) + " id " + cid + ": " + rs.why);
  return true;
}

LaneConfig Engine::update_thresholds(int id, std::optional<double> z, std::optional<double> area,
                                     std::optional<double> floor, const std::string& who) {
  Lane& l = lane(id);
  auto check = [](const char* name, std::optional<double> v) {
    if (v && !(std::isfinite(*v) && *v > 0))
      fail(name, " must be a finite number > 0 (got ", *v, ")");
  };
  check("z_threshold", z);
  check("min_fragment_area_mm2", area);
  check("floor_mm", floor);
  LaneConfig next;
  {
    std::lock_guard<std::mutex> lock(ctl_mu_);
    next = l.pending ? *l.pending : l.config;
    if (z) next.inspection.z_threshold = *z;
    if (area) next.inspection.min_fragment_area_mm2 = *area;
    if (floor) next.inspection.floor_mm = *floor;
    l.pending = next;
  }
  std::string detail = "lane " + std::to_string(id);
  if (z) detail += " z_threshold=" + std::to_string(*z);
  if (area) detail += " min_fragment_area_mm2=" + std::to_string(*area);
  if (floor) detail += " floor_mm=" + std::to_string(*floor);
  store_.audit(who, "lane.thresholds", detail);
  return next;
}

LaneState Engine::reset_lane(int id, const std::string& who, const std::string& reason) {
  Lane& l = lane(id);
  const std::string by = "encoder reset by " + (who.empty() ? std::string("unknown") : who) +
                         (reason.empty() ? "" : ": " + reason);
  {
    std::lock_guard<std::mutex> lock(mu_);
    l.admission.request_reset(by);
  }
  store_.audit(who, "lane.reset",
               "lane " + std::to_string(id) + (reason.empty() ? "" : " " + reason));
  return lane_state(id);
}

void Engine::sensor_lost(int id, const std::string& why) {
  Lane& l = lane(id);
  {
    std::lock_guard<std::mutex> lock(mu_);
    l.end_now = why;
  }
  cv_.notify_all();
  store_.audit("sensors", "lane.sensor_lost", "lane " + std::to_string(id) + " " + why);
}

}  // namespace rangex
