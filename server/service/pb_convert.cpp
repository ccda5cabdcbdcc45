#include "service/pb_convert.h"

#include <algorithm>

#include "core/calibration_report.h"
#include "core/error.h"
#include "core/plant_config.h"
#include "core/utf8.h"
#include "pipeline/learned_report.h"
#include "rangex/v1/decision_names.h"

namespace rangex {

namespace {

// Text from outside reaches these messages: a camera's vendor, model and serial are bytes of
// its registers, a database and a PLC name their own errors, a folder may be any path, and
// warnings and states repeat them. A protobuf string that is not UTF-8 leaves every client
// unable to read the whole message, so each string field, nested and repeated ones too, is
// made UTF-8 (U+FFFD for a byte that is not) once the message is filled.
void make_strings_utf8(google::protobuf::Message& m) {
  using google::protobuf::FieldDescriptor;
  const google::protobuf::Descriptor* d = m.GetDescriptor();
  const google::protobuf::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const FieldDescriptor* f = d->field(i);
    if (f->type() == FieldDescriptor::TYPE_STRING) {
      if (f->is_repeated()) {
        for (int k = 0; k < r->FieldSize(m, f); ++k)
          if (const std::string v = r->GetRepeatedString(m, f, k);
              invalid_utf8_at(v) != std::string::npos)
            r->SetRepeatedString(&m, f, k, valid_utf8(v));
      } else if (const std::string v = r->GetString(m, f);
                 invalid_utf8_at(v) != std::string::npos) {
        r->SetString(&m, f, valid_utf8(v));
      }
    } else if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE) {
      if (f->is_repeated()) {
        for (int k = 0; k < r->FieldSize(m, f); ++k)
          make_strings_utf8(*r->MutableRepeatedMessage(&m, f, k));
      } else if (r->HasField(m, f)) {
        make_strings_utf8(*r->MutableMessage(&m, f));
      }
    }
  }
}

}  // namespace

namespace pb = rangex::v1;

void fill(pb::FilletResult* o, const StoredFillet& f) {
  o->set_uid(f.uid);
  o->set_lane(f.lane);
  o->set_lane_fillet(f.lane_fillet);
  o->set_first_encoder(f.first_encoder);
  o->set_rows(f.rows);
  o->set_decision(decision_from_name(f.decision));
  o->set_reason(f.reason);
  o->set_beta0(f.beta0);
  o->set_beta1(f.beta1);
  o->set_beta2(f.beta2);
  o->set_residual_mean_dn(f.resid_mean_dn);
  o->set_residual_std_dn(f.resid_std_dn);
  o->set_calibration_id(f.calibration_id);
  o->set_decided_ns(f.decided_ns);
  o->set_belt_y0_mm(f.belt_y0_mm);
  for (const StoredFragment& g : f.fragments) {
    pb::Fragment* p = o->add_fragments();
    p->set_kind(g.kind);
    p->set_x_mm(g.x_mm);
    p->set_y_mm(g.y_mm);
    p->set_area_mm2(g.area_mm2);
    p->set_peak_z(g.peak_z);
    p->set_attenuation_mm2(g.attenuation_mm2);
    p->set_meat_mm(g.meat_mm);
    p->set_bone_mg(g.bone_mg);
    p->set_row0(g.row0);
    p->set_row1(g.row1);
    p->set_col0(g.col0);
    p->set_col1(g.col1);
  }
}

void fill(pb::CalibrationInfo* o, const StoredCalibration& c, bool with_yaml) {
  o->set_lane(c.lane);
  o->set_id(c.id);
  o->set_uploaded_ns(c.uploaded_ns);
  o->set_active(c.active);
  if (with_yaml) o->set_yaml(c.yaml), o->set_report_json(c.report);
  const ReportStatus rs = check_calibration_report(c.report);
  o->set_report_status(rs.passed ? "passed" : rs.why);
}

void fill(pb::LearnedSettingsInfo* o, const StoredSetting& c, bool full) {
  o->set_lane(c.lane);
  o->set_id(c.id);
  o->set_uploaded_ns(c.uploaded_ns);
  o->set_active(c.active);
  if (full) o->set_yaml(c.yaml), o->set_report_json(c.report);
  const LearnedReportStatus rs = check_learned_report(c.report, c.lane);
  o->set_report_status(rs.passed ? "passed" : rs.why);
  for (int64_t f : rs.flagged) o->add_flagged_fillets(f);
  for (int64_t f : rs.kept) o->add_kept_fillets(f);
  try {
    const LearnedDetection L = parse_learned_detection(c.yaml, "learned settings " + c.id);
    o->set_fillets(L.fillets);
    o->set_false_reject_target(L.target_frr);
    for (const std::string& line : L.sensitivity) o->add_sensitivity(line);
  } catch (const Error&) {
    // Checked at upload; a stored version that no longer reads shows without them.
  }
}

void fill(pb::LaneInfo* o, const LaneState& s) {
  const LaneConfig& l = s.config;
  o->set_id(l.id);
  o->set_frame_width(l.frame_width);
  o->set_frame_height(l.frame_height);
  o->set_xray_pixels(l.xray.pixels);
  o->set_encoder_step_mm(l.encoder_step_mm);
  o->set_calibration_id(s.calibration_id);
  o->set_z_threshold(l.inspection.z_threshold);
  o->set_min_fragment_area_mm2(l.inspection.min_fragment_area_mm2);
  o->set_floor_mm(l.inspection.floor_mm);
  o->set_fed(s.fed);
  if (s.fed) o->set_last_encoder(s.last_encoder);
  o->set_lines_accepted(s.accepted);
  o->set_idle_ms(s.idle_ms);
  o->set_fillet_in_progress(s.fillet_in_progress);
  o->set_restarts(s.restarts);
  o->set_last_restart(s.last_restart);
  const LearnedDetection& L = l.inspection.learned;
  if (L.active()) {
    o->set_learned_version(L.version);
    for (const std::string& line : L.sensitivity) o->add_learned_sensitivity(line);
  }
  o->set_false_reject_target(l.inspection.false_reject_target);
  o->set_implied_false_reject_rate(s.implied_frr);
  o->set_drift_fillets(s.drift_fillets);
  o->set_product_drift(s.product_drift);
  o->set_plc_state(s.plc);
  {
    const LaneVerification& v = s.verification;
    pb::LaneVerification* pv = o->mutable_verification();
    if (v.last) {
      pv->set_has_last(true);
      pv->set_piece(v.last->piece);
      pv->set_passed(v.last->passed);
      pv->set_who(v.last->who);
      pv->set_unix_ns(v.last->unix_ns);
      pv->set_fillet_uid(v.last->fillet_uid);
      pv->set_found_x_mm(v.last->found_x_mm);
      pv->set_detail(v.last->detail);
    }
    pv->set_running(v.running);
    pv->set_running_piece(v.running_piece);
    pv->set_fillets_left(v.fillets_left);
    pv->set_overdue(v.overdue);
  }
  if (s.sensors) {
    pb::LaneSensors* ls = o->mutable_sensors();
    ls->set_trigger(s.sensors->trigger);
    ls->set_lines(s.sensors->lines);
    ls->set_incomplete_lines(s.sensors->incomplete);
    ls->set_refused_lines(s.sensors->refused);
    for (const SensorState& d : s.sensors->devices) {
      pb::SensorDevice* pd = ls->add_devices();
      pd->set_role(d.role);
      pd->set_device(d.device);
      pd->set_description(d.description);
      pd->set_state(d.state);
      pd->set_error(d.error);
      pd->set_frames(d.frames);
      pd->set_incomplete(d.incomplete);
      pd->set_lost_frames(d.lost_frames);
      pd->set_wrong_format(d.wrong_format);
      pd->set_lacked(d.lacked);
      pd->set_stale(d.stale);
      pd->set_underruns(d.underruns);
      pd->set_reconnects(d.reconnects);
    }
  }
  make_strings_utf8(*o);
}

void fill(pb::RecordingStatus* o, const RecordingStatus& r) {
  o->set_active(r.active);
  o->set_name(r.name);
  o->set_dir(r.dir);
  for (int l : r.lanes) o->add_lanes(l);
  o->set_minutes(r.minutes);
  o->set_started_unix_ns(r.started_unix_ns);
  o->set_lines(r.lines);
  o->set_left_out(r.left_out);
  o->set_bytes(r.bytes);
  o->set_budget_bytes(r.budget_bytes);
  o->set_estimate_bytes(r.estimate_bytes);
  o->set_ended(r.ended);
  make_strings_utf8(*o);
}

void fill(pb::GetStatisticsResponse* o, const EngineStats& s) {
  o->set_open_files(std::max<int64_t>(s.open_files, 0));
  o->set_open_files_limit(s.open_files_limit);
  if (!s.recording.name.empty()) fill(o->mutable_recording(), s.recording);
  if (s.plc) {
    pb::PlcStatus* p = o->mutable_plc();
    p->set_address(s.plc->address);
    p->set_connected(s.plc->connected);
    p->set_error(s.plc->error);
    p->set_released(s.plc->released);
    p->set_diverted(s.plc->diverted);
    p->set_late(s.plc->late);
    p->set_unreleased(s.plc->unreleased);
    p->set_pending(s.plc->pending);
    p->set_reconnects(s.plc->reconnects);
    p->set_least_spare_ms(s.plc->least_spare_ms);
    p->set_refused(s.plc->refused);
  }
  if (s.forwarding) {
    const ForwarderStatus& f = *s.forwarding;
    pb::ForwardingStatus* p = o->mutable_forwarding();
    p->set_server_id(f.server_id);
    p->set_database(f.database);
    p->set_connected(f.connected);
    p->set_state(f.state);
    p->set_error(f.last_error);
    p->set_lag_records(f.lag_records);
    p->set_lag_seconds(f.lag_seconds);
    p->set_forwarded_seq(f.forwarded_seq);
    p->set_head_seq(f.head_seq);
    p->set_links(uint64_t(f.links));
    p->set_images(uint64_t(f.images));
    p->set_failures(uint64_t(f.failures));
  }
  o->set_lines_per_second(s.lines_per_second);
  o->set_lines_received(s.received);
  o->set_lines_accepted(s.accepted);
  o->set_lines_processed(s.processed);
  for (const auto& [reason, n] : s.refused) {
    pb::ReasonCount* d = o->add_refused();
    d->set_reason(reason);
    d->set_lines(n);
  }
  for (const auto& [reason, n] : s.dropped) {
    pb::ReasonCount* d = o->add_dropped();
    d->set_reason(reason);
    d->set_lines(n);
  }
  auto lat = [&](const char* stage, const LatencyStats::Summary& l) {
    pb::Latency* p = o->add_latencies();
    p->set_stage(stage);
    p->set_p50_ms(l.p50);
    p->set_p99_ms(l.p99);
    p->set_samples(l.samples);
    p->set_sum_ms(l.sum_ms);
    for (size_t k = 0; k < LatencyStats::kBoundsMs.size(); ++k) {
      p->add_bucket_le_ms(LatencyStats::kBoundsMs[k]);
      p->add_bucket_count(l.cumulative[k]);
    }
  };
  lat("queue_wait", s.queue_wait);
  lat("line_pipeline_batch", s.pipeline);
  lat("inspection_fillet", s.inspection);
  lat("last_line_to_decision", s.decision);
  lat("inspection_wait", s.inspection_wait);
  lat("store_decision", s.store);
  for (const auto& [name, l] : s.inspection_stages) {
    std::string stage = "inspection_" + name;
    for (char& c : stage)
      if (c == ' ') c = '_';
    lat(stage.c_str(), l);
  }
  o->set_queue_depth(s.queue_depth);
  o->set_queue_capacity(s.queue_capacity);
  o->set_fillets(s.fillets);
  o->set_rejects(s.rejects);
  o->set_not_inspected(s.not_inspected);
  o->set_lane_restarts(s.lane_restarts);
  o->set_store_errors(s.store_errors);
  o->set_serving(s.health.serving);
  for (const std::string& r : s.health.reasons) o->add_health(r);
  for (const std::string& w : s.warnings) o->add_warnings(w);
  o->set_backend(s.backend.name);
  o->set_device(s.backend.device);
  o->set_backend_note(s.backend_note);
  o->set_batches(s.batches.batches);
  o->set_batches_verified(s.batches.verified);
  o->set_verify_mismatches(s.batches.mismatches);
  o->set_backend_failures(s.batches.failures);
  make_strings_utf8(*o);
}

}  // namespace rangex
