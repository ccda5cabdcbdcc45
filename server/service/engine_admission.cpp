// Admission: each line checked against its lane (size, count, calibration) and queued, or
// refused with a code and a message; the feeder's credit and durable count come back with it.
#include <algorithm>
#include <optional>

#include "core/error.h"
#include "service/engine.h"
#include "service/line_shape.h"
#include "service/steady_ns.h"

namespace rangex {

namespace {
// After the store recovers, a lane whose lines were handed back refuses later counts this
// long at most while it waits for the first handed-back count to come again.
constexpr double kHandBackHoldS = 10;
}  // namespace

Engine::Verdict Engine::refuse(Lane* l, Refusal code, std::string message, size_t queued) {
  ++refused_[size_t(code)];
  if (l) ++l->refused[size_t(code)];
  Verdict v;
  v.code = code;
  v.message = std::move(message);
  v.credit = int(opt_.queue_lines - std::min(queued, opt_.queue_lines));
  if (l) v.durable = l->durable_saved;
  return v;
}

Engine::Verdict Engine::refuse_empty(uint64_t sequence) {
  ++received_;
  return refuse(nullptr, Refusal::kMissingLine,
                "request " + std::to_string(sequence) + " carries no line", queued_.load());
}

int Engine::free_places() const {
  return int(opt_.queue_lines - std::min(queued_.load(), opt_.queue_lines));
}

Engine::Verdict Engine::submit(IncomingLine&& line) {
  ++received_;
  // A sensor's lines are lent by its receive buffers: nothing was parsed out of a message.
  for (const LineBytes* b : {&line.cam0, &line.cam1, &line.xray, &line.xray_high})
    if (!b->is_lent()) bytes_parsed_ += b->size();
  const auto found = by_id_.find(line.lane);
  Lane* l = found == by_id_.end() ? nullptr : found->second;
  if (!l)
    return refuse(nullptr, Refusal::kUnknownLane, "unknown lane " + std::to_string(line.lane),
                  queued_.load());
  ++l->received;
  if (auto bad = check_line_shape({l->id, l->width, l->height, l->pixels, l->energies}, line))
    return refuse(l, bad->code, std::move(bad->message), queued_.load());

  // A shift recording takes its copy here, outside the lock, and keeps it if the line is taken.
  std::optional<ShiftRecorder::Line> recorded;
  if (shift_->wants(l->id)) recorded = ShiftRecorder::copy(line);

  // The checks against the lane's state and the update of that state are one step under
  // mu_: two streams on one lane can never both be accepted for a count.
  const int64_t now = steady_ns();
  Verdict v;
  {
    std::lock_guard<std::mutex> lock(mu_);
    // Idle counts from the last line received, refused ones too: a feeder that resends after
    // a restart is feeding the lane even while every line is a duplicate.
    l->last_line_ns = now;
    if (stopping_)
      return refuse(l, Refusal::kShuttingDown,
                    "the server is shutting down: line handed back, send it to the next one",
                    queue_.size());
    // While decisions cannot be stored, lines are handed back rather than accepted into
    // memory that an exit would lose; the lane then takes its counts in order again.
    if (line.encoder <= l->handback_from) l->handback_from = INT64_MAX;  // the resend is here
    if (recorder_.failing()) {
      l->handback_from = std::min(l->handback_from, line.encoder);
      l->handback_ns = now;
      return refuse(l, Refusal::kStoreUnavailable,
                    "the store cannot write: line handed back, send it again when the store "
                    "recovers (health says why)",
                    queue_.size());
    }
    if (l->handback_from != INT64_MAX && now - l->handback_ns < seconds_ns(kHandBackHoldS))
      return refuse(l, Refusal::kStoreUnavailable,
                    join("line handed back: lane ", l->id, " waits for count ", l->handback_from,
                         ", handed back before it, to be sent again"),
                    queue_.size());
    l->handback_from = INT64_MAX;
    if (!line.calibration_id.empty() && line.calibration_id != l->admit_calibration)
      return refuse(l, Refusal::kCalibrationMismatch,
                    join("line made with calibration '", line.calibration_id, "' but lane ", l->id,
                         " runs '", l->admit_calibration, "'"),
                    queue_.size());
    LaneAdmission::Verdict a = l->admission.check(line.encoder);
    if (a.outcome == LaneAdmission::Outcome::kDuplicate)
      return refuse(l, Refusal::kDuplicateLine, std::move(a.message), queue_.size());
    if (a.outcome == LaneAdmission::Outcome::kBackwards)
      return refuse(l, Refusal::kEncoderBackwards, std::move(a.message), queue_.size());
    if (queue_.size() >= opt_.queue_lines)
      // The line is lost: its count stays unaccounted, so the assembly sees a gap and fails
      // the fillets around it safe.
      return refuse(l, Refusal::kOverload,
                    join("queue full (", opt_.queue_lines,
                         " lines); line dropped, its fillet will be rejected as not inspected"),
                    queue_.size());
    l->admission.commit(line.encoder, !a.restart.empty());
    if (line.queued_by) ++*line.queued_by;
    ++l->accepted;
    queue_.push(l->slot, {std::move(line), now, std::move(a.restart)});
    queued_ = queue_.size();
    ++accepted_;
    v.accepted = true;
    v.credit = int(opt_.queue_lines - queue_.size());
    v.durable = l->durable_saved;
  }
  cv_.notify_one();
  if (recorded) shift_->offer(std::move(*recorded));
  return v;
}

void Engine::pause(bool paused) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    paused_ = paused;
  }
  cv_.notify_all();
}

}  // namespace rangex
