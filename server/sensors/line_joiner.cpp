#include "sensors/line_joiner.h"

#include <algorithm>

namespace rangex {

namespace {
constexpr unsigned kAll = (1u << kLaneDevices) - 1;
}

LineJoiner::LineJoiner(Emit emit, int64_t window) : emit_(std::move(emit)), window_(window) {}

void LineJoiner::add(int device, int64_t count, LineBytes frame) {
  std::lock_guard<std::mutex> lk(mu_);
  std::optional<int64_t>& last = latest_[size_t(device)];
  if ((last && count <= *last) || (next_ && count < *next_)) {
    ++stats_.stale[size_t(device)];
    return;
  }
  last = count;
  newest_ = std::max(newest_, count);
  Partial& p = pending_[count];
  p.frames[size_t(device)] = std::move(frame);
  p.mask |= 1u << device;
  if (!next_) {
    // The lane starts at the first count every device has reached: earlier frames of the
    // devices that started first have no partners (nothing of it was inspected yet).
    int64_t start = INT64_MIN;
    for (const auto& l : latest_) {
      if (!l) return;
      start = std::max(start, *l);
    }
    next_ = start;
    pending_.erase(pending_.begin(), pending_.lower_bound(start));
  }
  advance();
}

void LineJoiner::give_up(Partial* p) {
  ++stats_.incomplete;
  for (int d = 0; d < kLaneDevices; ++d)
    if (!(p->mask & (1u << d))) ++stats_.lacked[size_t(d)];
}

void LineJoiner::advance() {
  while (!pending_.empty()) {
    auto it = pending_.begin();
    if (it->first > *next_) {
      // Counts before the first pending one that every device has passed were seen by none:
      // skip to it (a gap in the counts; frames lost by all are counted by their devices).
      bool passed = true;
      for (const auto& l : latest_) passed = passed && *l >= it->first;
      if (!passed && newest_ - *next_ <= window_) return;
      next_ = it->first;
    }
    Partial& p = it->second;
    if (p.mask == kAll) {
      const int64_t count = it->first;
      std::array<LineBytes, kLaneDevices> frames = std::move(p.frames);
      pending_.erase(it);
      next_ = count + 1;
      ++stats_.lines;
      emit_(count, std::move(frames));
      continue;
    }
    // Incomplete: final once every device it lacks has moved past it, or it is too old.
    bool final = newest_ - it->first > window_;
    if (!final) {
      final = true;
      for (int d = 0; d < kLaneDevices; ++d)
        if (!(p.mask & (1u << d))) final = final && *latest_[size_t(d)] > it->first;
    }
    if (!final) return;
    give_up(&p);
    next_ = it->first + 1;
    pending_.erase(it);
  }
}

void LineJoiner::reset() {
  std::lock_guard<std::mutex> lk(mu_);
  pending_.clear();
  latest_ = {};
  next_.reset();
  newest_ = INT64_MIN;
}

std::optional<int64_t> LineJoiner::newest() const {
  std::lock_guard<std::mutex> lk(mu_);
  if (newest_ == INT64_MIN) return std::nullopt;
  return newest_;
}

JoinerStats LineJoiner::stats() const {
  std::lock_guard<std::mutex> lk(mu_);
  return stats_;
}

}  // namespace rangex
