#include "service/metrics_text.h"

#include <cinttypes>
#include <cstdio>

namespace rangex {

namespace {

// A label value, escaped as the format requires (backslash, quote, newline).
std::string label_value(const std::string& v) {
  std::string out = "\"";
  for (char c : v) {
    if (c == '\\' || c == '"')
      out += '\\', out += c;
    else if (c == '\n')
      out += "\\n";
    else
      out += c;
  }
  return out + "\"";
}

class Writer {
 public:
  void family(const char* name, const char* type, const char* help) {
    out_ += "# HELP ";
    out_ += name;
    out_ += ' ';
    out_ += help;
    out_ += "\n# TYPE ";
    out_ += name;
    out_ += ' ';
    out_ += type;
    out_ += '\n';
  }
  void sample(const std::string& name, const std::string& labels, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    out_ += name;
    if (!labels.empty()) out_ += "{" + labels + "}";
    out_ += ' ';
    out_ += buf;
    out_ += '\n';
  }
  void sample(const std::string& name, const std::string& labels, uint64_t v) {
    out_ += name;
    if (!labels.empty()) out_ += "{" + labels + "}";
    out_ += ' ';
    out_ += std::to_string(v);
    out_ += '\n';
  }
  // A histogram in seconds from one in milliseconds.
  void histogram(const std::string& name, const std::string& labels,
                 const LatencyStats::Summary& l) {
    const std::string sep = labels.empty() ? "" : labels + ",";
    for (size_t k = 0; k < LatencyStats::kBoundsMs.size(); ++k) {
      char le[32];
      std::snprintf(le, sizeof le, "%g", LatencyStats::kBoundsMs[k] / 1e3);
      sample(name + "_bucket", sep + "le=\"" + le + "\"", l.cumulative[k]);
    }
    sample(name + "_bucket", sep + "le=\"+Inf\"", l.samples);
    sample(name + "_sum", labels, l.sum_ms / 1e3);
    sample(name + "_count", labels, l.samples);
  }
  std::string str() && { return std::move(out_); }

 private:
  std::string out_;
};

std::string lane_label(int lane) {
  return "lane=\"" + std::to_string(lane) + "\"";
}

// Lines and fillets by lane: received, processed, refused, dropped, decided; restarts.
void lane_counters(Writer& w, const EngineStats& s, const std::vector<LaneState>& lanes) {
  w.family("rangex_lines_received_total", "counter",
           "Lines received, by lane (lane=\"none\": requests naming no lane of this plant).");
  uint64_t laneless = s.received;
  for (const LaneState& l : lanes) {
    w.sample("rangex_lines_received_total", lane_label(l.config.id), l.received);
    laneless -= std::min(laneless, l.received);
  }
  w.sample("rangex_lines_received_total", "lane=\"none\"", laneless);

  w.family("rangex_lines_processed_total", "counter",
           "Lines through the line stages and into their lane's assembly, by lane.");
  for (const LaneState& l : lanes)
    w.sample("rangex_lines_processed_total", lane_label(l.config.id), l.processed);

  w.family("rangex_lines_refused_total", "counter",
           "Lines refused at admission, by lane and code (lane=\"none\": unknown lane or no "
           "line).");
  for (const auto& [code, n] : s.refused) {
    uint64_t rest = n;
    for (const LaneState& l : lanes)
      if (const auto it = l.refused.find(code); it != l.refused.end()) {
        w.sample("rangex_lines_refused_total",
                 lane_label(l.config.id) + ",code=" + label_value(code), it->second);
        rest -= std::min(rest, it->second);
      }
    if (rest)
      w.sample("rangex_lines_refused_total", "lane=\"none\",code=" + label_value(code), rest);
  }

  w.family("rangex_lines_dropped_total", "counter",
           "Lines accepted and then not processed, by lane and reason.");
  for (const LaneState& l : lanes)
    for (const auto& [reason, n] : l.dropped)
      w.sample("rangex_lines_dropped_total",
               lane_label(l.config.id) + ",reason=" + label_value(reason), n);

  w.family("rangex_fillets_total", "counter", "Fillets decided, by lane and decision.");
  for (const LaneState& l : lanes) {
    const std::string lane = lane_label(l.config.id);
    w.sample("rangex_fillets_total", lane + ",decision=\"pass\"",
             l.fillets - l.rejects - l.not_inspected);
    w.sample("rangex_fillets_total", lane + ",decision=\"reject\"", l.rejects);
    w.sample("rangex_fillets_total", lane + ",decision=\"not_inspected\"", l.not_inspected);
  }

  w.family("rangex_lane_restarts_total", "counter",
           "Lane restarts (encoder resets, jumps, lanes that stopped being fed), by lane.");
  for (const LaneState& l : lanes)
    w.sample("rangex_lane_restarts_total", lane_label(l.config.id), l.restarts);
}

// Positive release to the line's PLC.
void plc_metrics(Writer& w, const PlcStatus& p) {
  const std::string at = "plc=" + label_value(p.address);
  w.family("rangex_plc_up", "gauge", "1 while the PLC's Modbus TCP link is up.");
  w.sample("rangex_plc_up", at, uint64_t(p.connected));
  w.family("rangex_plc_fillets_total", "counter",
           "Fillets by what the PLC was told: released (clean, in time), diverted (rejected or "
           "not inspected), late (clean, decided after the deadline), unreleased (clean, the "
           "PLC unreachable, or refusing the release ring, until the deadline).");
  w.sample("rangex_plc_fillets_total", at + ",result=\"released\"", p.released);
  w.sample("rangex_plc_fillets_total", at + ",result=\"diverted\"", p.diverted);
  w.sample("rangex_plc_fillets_total", at + ",result=\"late\"", p.late);
  w.sample("rangex_plc_fillets_total", at + ",result=\"unreleased\"", p.unreleased);
  w.family("rangex_plc_refusing", "gauge",
           "1 while the PLC answers writes of some of its registers with a Modbus exception.");
  w.sample("rangex_plc_refusing", at, uint64_t(!p.refused.empty()));
  w.family("rangex_plc_pending", "gauge", "Releases waiting to be sent.");
  w.sample("rangex_plc_pending", at, p.pending);
  w.family("rangex_plc_least_spare_seconds", "gauge",
           "The least time to spare of a release sent (-1: none yet).");
  w.sample("rangex_plc_least_spare_seconds", at,
           p.least_spare_ms < 0 ? -1.0 : p.least_spare_ms / 1e3);
}

// Forwarding to the plant-wide database.
void forwarding_metrics(Writer& w, const ForwarderStatus& f) {
  const std::string at = "server_id=" + label_value(f.server_id);
  w.family("rangex_forward_up", "gauge", "1 while forwarding to the plant-wide PostgreSQL works.");
  w.sample("rangex_forward_up", at, uint64_t(f.connected));
  w.family("rangex_forward_lag_records", "gauge",
           "Chain links stored here and not yet in the plant-wide database.");
  w.sample("rangex_forward_lag_records", at, uint64_t(std::max<int64_t>(0, f.lag_records)));
  w.family("rangex_forward_lag_seconds", "gauge", "The age of the oldest of them.");
  w.sample("rangex_forward_lag_seconds", at, f.lag_seconds);
  w.family("rangex_forward_links_total", "counter",
           "Chain links (decisions and audit entries) forwarded since the server started.");
  w.sample("rangex_forward_links_total", at, uint64_t(f.links));
  w.family("rangex_forward_failures_total", "counter",
           "Failed connections or batches (each retried; nothing is dropped).");
  w.sample("rangex_forward_failures_total", at, uint64_t(f.failures));
}

// Lanes fed by their own GigE Vision devices.
void sensor_metrics(Writer& w, const std::vector<LaneState>& lanes) {
  auto device_label = [](int lane, const SensorState& d) {
    return lane_label(lane) + ",role=" + label_value(d.role) + ",device=" + label_value(d.device);
  };
  w.family("rangex_sensor_up", "gauge",
           "1 while a lane's GigE Vision device streams, 0 otherwise (connecting, lost, refused).");
  for (const LaneState& l : lanes)
    if (l.sensors)
      for (const SensorState& d : l.sensors->devices)
        w.sample("rangex_sensor_up", device_label(l.config.id, d),
                 uint64_t(d.state == "streaming"));
  struct Counter {
    const char* name;
    const char* help;
    uint64_t SensorState::*field;
  };
  const Counter counters[] = {
      {"rangex_sensor_frames_total", "Complete frames taken from the device.",
       &SensorState::frames},
      {"rangex_sensor_incomplete_frames_total", "Frames with lost packets (missing lines).",
       &SensorState::incomplete},
      {"rangex_sensor_lost_frames_total", "Frames that never arrived (gaps in the frame ids).",
       &SensorState::lost_frames},
      {"rangex_sensor_wrong_format_frames_total", "Frames of another pixel format or size.",
       &SensorState::wrong_format},
      {"rangex_sensor_lacked_lines_total", "Lines given up for want of this device's frame.",
       &SensorState::lacked},
      {"rangex_sensor_underruns_total", "Frames dropped for want of a free receive buffer.",
       &SensorState::underruns},
      {"rangex_sensor_reconnects_total", "Sessions after the first (the device dropped off).",
       &SensorState::reconnects}};
  for (const Counter& c : counters) {
    w.family(c.name, "counter", c.help);
    for (const LaneState& l : lanes)
      if (l.sensors)
        for (const SensorState& d : l.sensors->devices)
          w.sample(c.name, device_label(l.config.id, d), d.*c.field);
  }
}

// Learned thresholds and drift: what the lane's recently passed fillets imply.
void learned_metrics(Writer& w, const std::vector<LaneState>& lanes) {
  w.family("rangex_lane_implied_false_reject_rate", "gauge",
           "With learned thresholds: the per-fillet false-reject rate the lane's recently passed "
           "fillets imply under its learned model (-1: not estimated yet), by lane and version.");
  for (const LaneState& l : lanes)
    if (l.config.inspection.learned.active())
      w.sample(
          "rangex_lane_implied_false_reject_rate",
          lane_label(l.config.id) + ",version=" + label_value(l.config.inspection.learned.version),
          l.implied_frr);
  w.family("rangex_lane_product_drift", "gauge",
           "1 when a lane's product is rougher than learned (implied false rejects above twice "
           "the target): re-learn.");
  for (const LaneState& l : lanes)
    if (l.config.inspection.learned.active())
      w.sample("rangex_lane_product_drift", lane_label(l.config.id), l.product_drift ? 1.0 : 0.0);
}

// The line stages' batches on the backend, and the store's failed writes.
void batch_counters(Writer& w, const EngineStats& s) {
  w.family("rangex_batches_total", "counter", "Line batches computed by the backend.");
  w.sample("rangex_batches_total", "", s.batches.batches);
  w.family("rangex_batches_verified_total", "counter",
           "Device batches recomputed on the CPU reference and compared.");
  w.sample("rangex_batches_verified_total", "", s.batches.verified);
  w.family("rangex_verify_mismatches_total", "counter",
           "Verified batches whose device results differed from the CPU's (decided from the "
           "CPU's).");
  w.sample("rangex_verify_mismatches_total", "", s.batches.mismatches);
  w.family("rangex_backend_failures_total", "counter",
           "Device failures (the server went on on the CPU).");
  w.sample("rangex_backend_failures_total", "", s.batches.failures);
  w.family("rangex_store_errors_total", "counter", "Failed writes to the store.");
  w.sample("rangex_store_errors_total", "", s.store_errors);
}

// Each stage's latency and the decision's, as histograms in seconds.
void latency_histograms(Writer& w, const EngineStats& s) {
  w.family("rangex_stage_latency_seconds", "histogram",
           "Latency of each stage: queue_wait (a line), line_batch (a batch through the line "
           "stages), inspection_wait and inspection (a fillet), inspection_<part>, store.");
  w.histogram("rangex_stage_latency_seconds", "stage=\"queue_wait\"", s.queue_wait);
  w.histogram("rangex_stage_latency_seconds", "stage=\"line_batch\"", s.pipeline);
  w.histogram("rangex_stage_latency_seconds", "stage=\"inspection_wait\"", s.inspection_wait);
  w.histogram("rangex_stage_latency_seconds", "stage=\"inspection\"", s.inspection);
  for (const auto& [name, l] : s.inspection_stages) {
    std::string stage = "inspection_" + name;
    for (char& c : stage)
      if (c == ' ') c = '_';
    w.histogram("rangex_stage_latency_seconds", "stage=" + label_value(stage), l);
  }
  w.histogram("rangex_stage_latency_seconds", "stage=\"store\"", s.store);
  w.family("rangex_decision_latency_seconds", "histogram",
           "From the arrival of a fillet's last line to its decision being stored and "
           "published.");
  w.histogram("rangex_decision_latency_seconds", "", s.decision);
}

// What is now: the queue, rates, streams, health, the backend and each lane's calibration.
void gauges(Writer& w, const MetricsInput& m) {
  const EngineStats& s = m.stats;
  w.family("rangex_queue_depth_lines", "gauge", "Lines waiting for the worker.");
  w.sample("rangex_queue_depth_lines", "", uint64_t(s.queue_depth));
  w.family("rangex_queue_capacity_lines", "gauge", "Lines the queue holds at most.");
  w.sample("rangex_queue_capacity_lines", "", uint64_t(s.queue_capacity));
  w.family("rangex_lines_per_second", "gauge", "Lines processed per second, recently.");
  w.sample("rangex_lines_per_second", "", s.lines_per_second);
  w.family("rangex_subscribers", "gauge",
           "Live result subscribers (gRPC streams and the dashboard's event streams).");
  w.sample("rangex_subscribers", "", uint64_t(m.subscribers));
  w.family("rangex_subscribers_dropped_total", "counter",
           "Result subscribers that fell behind and gave way to a new one.");
  w.sample("rangex_subscribers_dropped_total", "", m.subscribers_dropped);
  w.family("rangex_http_event_streams", "gauge", "The dashboard's open event streams.");
  w.sample("rangex_http_event_streams", "", uint64_t(m.http_clients));
  w.family("rangex_ingest_streams", "gauge", "Open StreamLines calls.");
  w.sample("rangex_ingest_streams", "", uint64_t(m.ingest_streams));
  if (s.open_files >= 0) {
    w.family("rangex_open_files", "gauge",
             "Files the process holds, each client connection one (near the limit, new "
             "connections are refused).");
    w.sample("rangex_open_files", "", uint64_t(s.open_files));
  }
  if (s.open_files_limit > 0) {
    w.family("rangex_open_files_limit", "gauge", "The process's soft limit on open files.");
    w.sample("rangex_open_files_limit", "", s.open_files_limit);
  }
  w.family("rangex_serving", "gauge", "1 when the server can inspect (health SERVING).");
  w.sample("rangex_serving", "", uint64_t(s.health.serving ? 1 : 0));
  w.family("rangex_backend_info", "gauge", "The backend running the line stages (value 1).");
  w.sample("rangex_backend_info",
           "backend=" + label_value(s.backend.name) + ",device=" + label_value(s.backend.device),
           uint64_t(1));
  w.family("rangex_lane_calibration_info", "gauge", "Each lane's active calibration (value 1).");
  for (const LaneState& l : m.lanes)
    w.sample("rangex_lane_calibration_info",
             lane_label(l.config.id) + ",calibration=" + label_value(l.calibration_id),
             uint64_t(1));
  w.family("rangex_lane_idle_seconds", "gauge",
           "Seconds since each fed lane's last accepted line.");
  for (const LaneState& l : m.lanes)
    if (l.idle_ms >= 0)
      w.sample("rangex_lane_idle_seconds", lane_label(l.config.id), double(l.idle_ms) / 1e3);
}

}  // namespace

std::string prometheus_text(const MetricsInput& m) {
  Writer w;
  lane_counters(w, m.stats, m.lanes);
  if (m.stats.plc) plc_metrics(w, *m.stats.plc);
  if (m.stats.forwarding) forwarding_metrics(w, *m.stats.forwarding);
  sensor_metrics(w, m.lanes);
  learned_metrics(w, m.lanes);
  batch_counters(w, m.stats);
  latency_histograms(w, m.stats);
  gauges(w, m);
  return std::move(w).str();
}

}  // namespace rangex
