#include "service/http_json.h"

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "core/json_text.h"
#include "pipeline/product_drift.h"
#include "service/http_server.h"
#include "service/image_view.h"

namespace rangex {

using json = nlohmann::json;

namespace {
json fragment_json(const StoredFragment& g) {
  return {{"kind", g.kind},         {"x_mm", g.x_mm},     {"y_mm", g.y_mm},
          {"area_mm2", g.area_mm2}, {"peak_z", g.peak_z}, {"attenuation_mm2", g.attenuation_mm2},
          {"meat_mm", g.meat_mm},   {"row0", g.row0},     {"row1", g.row1},
          {"col0", g.col0},         {"col1", g.col1},     {"bone_mg", g.bone_mg}};
}

const LaneCounts* find_lane(const HistorySample& s, int lane) {
  for (const LaneCounts& c : s.lanes)
    if (c.lane == lane) return &c;
  return nullptr;
}
}  // namespace

json fillet_json(const StoredFillet& f) {
  json frags = json::array();
  for (const StoredFragment& g : f.fragments) frags.push_back(fragment_json(g));
  return {{"uid", f.uid},
          {"lane", f.lane},
          {"lane_fillet", f.lane_fillet},
          {"first_encoder", f.first_encoder},
          {"rows", f.rows},
          {"decision", f.decision},
          {"reason", f.reason},
          {"calibration", f.calibration_id},
          {"beta0", f.beta0},
          {"beta1", f.beta1},
          {"beta2", f.beta2},
          {"resid_mean_dn", f.resid_mean_dn},
          {"resid_std_dn", f.resid_std_dn},
          {"belt_y0_mm", f.belt_y0_mm},
          {"decided_ns", f.decided_ns},
          {"fragments", frags}};
}

json audit_json(const AuditEntry& e) {
  return {{"ts_ns", e.ts_ns}, {"who", e.who}, {"what", e.what}, {"detail", e.detail}};
}

namespace {
// A lane's line rate over the last 10 s, and its fillets, rejects and fillets not inspected
// over the last 5 minutes.
struct LaneRates {
  double line_rate = 0, fillets_per_min = 0, reject_rate = 0, ni_rate = 0;
};

LaneRates lane_rates(const LaneState& l, PlantHistory& h) {
  LaneRates r;
  HistorySample a, b;
  if (h.window(10'000'000'000, a, b)) {
    const LaneCounts *ca = find_lane(a, l.config.id), *cb = find_lane(b, l.config.id);
    const double dt = double(b.t_ns - a.t_ns) / 1e9;
    if (ca && cb && dt > 0) r.line_rate = double(cb->processed - ca->processed) / dt;
  }
  if (h.window(300'000'000'000, a, b)) {
    const LaneCounts *ca = find_lane(a, l.config.id), *cb = find_lane(b, l.config.id);
    const double dt = double(b.t_ns - a.t_ns) / 1e9;
    if (ca && cb && dt > 0) {
      const double n = double(cb->fillets - ca->fillets);
      r.fillets_per_min = 60 * n / dt;
      if (n > 0) {
        r.reject_rate = double(cb->rejects - ca->rejects) / n;
        r.ni_rate = double(cb->not_inspected - ca->not_inspected) / n;
      }
    }
  }
  return r;
}

// The lane's light and the reason shown beside it: the first warning that holds, and a
// sensor that is not streaming over all of them (it leaves the lane blind).
std::pair<std::string, std::string> lane_light(const LaneState& l, double ni_rate) {
  std::string light = "green", why = "inspecting";
  if (!l.fed) {
    light = "grey", why = "never fed";
  } else if (l.idle_ms > 5000) {
    light = "red", why = "stopped: no line for " + std::to_string(l.idle_ms / 1000) + " s";
  } else if (ni_rate > 0.02) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.1f %% of the last 5 minutes' fillets not inspected",
                  100 * ni_rate);
    light = "amber", why = buf;
  }
  if (l.product_drift && light == "green")
    light = "amber", why = product_drift_warning(l.config.id, l.drift_fillets, l.implied_frr);
  if (l.plc.rfind("unreachable", 0) == 0 && light == "green")
    light = "amber", why = "PLC " + l.plc + ": every fillet is diverted";
  if (l.plc.rfind("refusing", 0) == 0 && light == "green")
    light = "amber", why = l.plc.substr(sizeof "refusing: " - 1);  // it says what it costs
  const LaneVerification& ver = l.verification;
  if (ver.overdue && light == "green")
    light = "amber", why = ver.last && !ver.last->passed
                               ? "the last verification failed: " + ver.last->detail
                               : "a verification is due";
  if (l.sensors)
    for (const SensorState& d : l.sensors->devices)
      if (d.state != "streaming" && light != "grey")
        light = "red",
        why = d.role + " (" + d.device + ") " + d.state + (d.error.empty() ? "" : ": " + d.error);
  return {light, why};
}

json verification_json(const LaneVerification& ver) {
  json verification = {{"running", ver.running},
                       {"running_piece", ver.running_piece},
                       {"fillets_left", ver.fillets_left},
                       {"overdue", ver.overdue},
                       {"last", nullptr}};
  if (ver.last)
    verification["last"] = {{"piece", ver.last->piece},
                            {"passed", ver.last->passed},
                            {"who", ver.last->who},
                            {"unix_ns", ver.last->unix_ns},
                            {"fillet_uid", ver.last->fillet_uid},
                            {"detail", ver.last->detail}};
  return verification;
}

json sensors_json(const LaneState& l) {
  if (!l.sensors) return nullptr;
  json devices = json::array();
  for (const SensorState& d : l.sensors->devices)
    devices.push_back({{"role", d.role},
                       {"device", d.device},
                       {"description", d.description},
                       {"state", d.state},
                       {"error", d.error},
                       {"frames", d.frames},
                       {"incomplete", d.incomplete},
                       {"lost_frames", d.lost_frames},
                       {"wrong_format", d.wrong_format},
                       {"lacked", d.lacked},
                       {"underruns", d.underruns},
                       {"reconnects", d.reconnects}});
  return {{"trigger", l.sensors->trigger},
          {"lines", l.sensors->lines},
          {"incomplete_lines", l.sensors->incomplete},
          {"refused_lines", l.sensors->refused},
          {"devices", devices}};
}
}  // namespace

json lane_json(const LaneState& l, PlantHistory& h, const std::string& backend) {
  const LaneRates r = lane_rates(l, h);
  const auto [light, why] = lane_light(l, r.ni_rate);
  const LearnedDetection& learned = l.config.inspection.learned;
  return {
      {"lane", l.config.id},
      {"learned_version", learned.active() ? learned.version : ""},
      {"learned_sensitivity", learned.active() ? learned.sensitivity : std::vector<std::string>{}},
      {"false_reject_target", l.config.inspection.false_reject_target},
      {"implied_false_reject_rate", l.implied_frr},
      {"drift_fillets", l.drift_fillets},
      {"product_drift", l.product_drift},
      {"fed", l.fed},
      {"idle_ms", l.idle_ms},
      {"calibration", l.calibration_id},
      {"fillet_in_progress", l.fillet_in_progress},
      {"restarts", l.restarts},
      {"last_restart", l.last_restart},
      {"received", l.received},
      {"processed", l.processed},
      {"fillets", l.fillets},
      {"rejects", l.rejects},
      {"not_inspected", l.not_inspected},
      {"refused", l.refused},
      {"dropped", l.dropped},
      {"line_rate", r.line_rate},
      {"fillets_per_min", r.fillets_per_min},
      {"reject_rate", r.reject_rate},
      {"not_inspected_rate", r.ni_rate},
      {"light", light},
      {"light_reason", why},
      {"backend", backend},
      {"sensors", sensors_json(l)},
      {"plc", l.plc},
      {"verification", verification_json(l.verification)}};
}

std::string server_health_text(Engine& engine, PlantHistory& h, const std::string& version) {
  const BackendInfo b = engine.backend();
  json lanes = json::array();
  for (const LaneState& l : engine.lanes()) lanes.push_back(lane_json(l, h, b.name));
  const Health health = engine.health();
  return json_dump(json{{"version", version},
                        {"serving", health.serving},
                        {"not_serving_because", health.reasons},
                        {"backend", b.name},
                        {"device", b.device},
                        {"lanes", lanes},
                        {"warnings", engine.stats().warnings}});
}

json image_kinds(Store& store, int64_t uid) {
  json kinds = json::array();
  for (const char* k : kImageKinds)
    if (store.image_path(uid, k)) kinds.push_back(k);
  return kinds;
}

void send_json(httplib::Response& res, const json& j) {
  res.set_content(json_dump(j), "application/json");
}

}  // namespace rangex
