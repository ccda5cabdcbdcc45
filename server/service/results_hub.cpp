#include "service/results_hub.h"

#include <algorithm>
#include <chrono>

namespace rangex {

std::shared_ptr<ResultsHub::Subscription> ResultsHub::subscribe(std::set<int> lanes,
                                                                std::set<std::string> decisions,
                                                                size_t capacity) {
  auto s = std::make_shared<Subscription>();
  s->lanes = std::move(lanes);
  s->decisions = std::move(decisions);
  s->capacity = std::max<size_t>(1, capacity);
  std::lock_guard<std::mutex> lock(mu_);
  subs_.push_back(s);
  return s;
}

void ResultsHub::unsubscribe(const std::shared_ptr<Subscription>& s) {
  std::lock_guard<std::mutex> lock(mu_);
  subs_.erase(std::remove(subs_.begin(), subs_.end(), s), subs_.end());
}

void ResultsHub::publish(const StoredFillet& f) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& s : subs_) {
      if (!s->lanes.empty() && !s->lanes.count(f.lane)) continue;
      if (!s->decisions.empty() && !s->decisions.count(f.decision)) continue;
      if (s->queue.size() >= s->capacity) {
        s->queue.pop_front();  // the slow subscriber loses its oldest, and is told
        ++s->lagged;
      }
      s->queue.push_back(f);
    }
  }
  cv_.notify_all();
}

bool ResultsHub::next(const std::shared_ptr<Subscription>& s, int timeout_ms, StoredFillet& out,
                      uint64_t& lagged) {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
               [&] { return !s->queue.empty() || s->closed; });
  if (s->queue.empty()) return false;
  out = std::move(s->queue.front());
  s->queue.pop_front();
  lagged = s->lagged;
  s->lagged = 0;
  return true;
}

void ResultsHub::close_all() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& s : subs_) s->closed = true;
  }
  cv_.notify_all();
}

int ResultsHub::subscribers() {
  std::lock_guard<std::mutex> lock(mu_);
  return int(subs_.size());
}

}  // namespace rangex
