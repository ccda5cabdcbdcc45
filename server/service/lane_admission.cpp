#include "service/lane_admission.h"

#include <algorithm>

namespace rangex {

LaneAdmission::LaneAdmission(int lane, int window, bool auto_reset)
    : lane_(lane),
      window_(uint64_t(std::max(64, window))),
      auto_reset_(auto_reset),
      bits_((window_ + 63) / 64, 0) {}

bool LaneAdmission::seen(int64_t e) const {
  const uint64_t i = uint64_t(e) % window_;
  return (bits_[i / 64] >> (i % 64)) & 1;
}

void LaneAdmission::mark(int64_t e, bool on) {
  const uint64_t i = uint64_t(e) % window_;
  if (on)
    bits_[i / 64] |= uint64_t(1) << (i % 64);
  else
    bits_[i / 64] &= ~(uint64_t(1) << (i % 64));
}

void LaneAdmission::clear() {
  std::fill(bits_.begin(), bits_.end(), 0);
}

LaneAdmission::Verdict LaneAdmission::check(int64_t e) const {
  Verdict v;
  if (!reset_.empty()) {
    v.restart = reset_;
    return v;
  }
  if (!fed_ || e > last_) return v;
  const std::string lane = "lane " + std::to_string(lane_);
  const uint64_t behind = uint64_t(last_) - uint64_t(e);
  if (behind < window_) {
    if (seen(e)) {
      v.outcome = Outcome::kDuplicate;
      v.message = "encoder " + std::to_string(e) + " of " + lane + " was already accepted";
    } else {
      v.outcome = Outcome::kBackwards;
      v.message = "encoder " + std::to_string(e) + " arrived after " + std::to_string(last_) +
                  " on " + lane + "; its place is already counted missing";
    }
    return v;
  }
  const std::string jump =
      "encoder went back from " + std::to_string(last_) + " to " + std::to_string(e);
  if (auto_reset_) {
    v.restart = jump + ": encoder reset";
    return v;
  }
  v.outcome = Outcome::kBackwards;
  v.message = jump + " on " + lane +
              "; if its encoder was reset, reset the lane (ControlService.ResetLane)";
  return v;
}

void LaneAdmission::commit(int64_t e, bool restarted) {
  if (restarted || !fed_) {
    clear();
    reset_.clear();
  } else if (e > last_) {
    // Slots between the last count and this one are reused from older counts: clear them.
    const uint64_t step = uint64_t(e) - uint64_t(last_);
    if (step >= window_)
      clear();
    else
      for (uint64_t k = 1; k < step; ++k) mark(last_ + int64_t(k), false);
  }
  mark(e, true);
  if (!fed_ || restarted || e > last_) last_ = e;
  fed_ = true;
}

void LaneAdmission::resume(int64_t durable) {
  clear();
  reset_.clear();
  for (uint64_t k = 0; k < window_; ++k) mark(durable - int64_t(k), true);
  last_ = durable;
  fed_ = true;
}

void LaneAdmission::request_reset(const std::string& why) {
  reset_ = why;
}

}  // namespace rangex
