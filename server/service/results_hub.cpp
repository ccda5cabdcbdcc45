#include "service/results_hub.h"

#include <algorithm>

namespace rangex {

std::shared_ptr<ResultsHub::Subscription> ResultsHub::subscribe(std::set<int> lanes,
                                                                std::set<std::string> decisions,
                                                                size_t capacity,
                                                                std::function<void()> wake) {
  auto s = std::make_shared<Subscription>();
  s->lanes = std::move(lanes);
  s->decisions = std::move(decisions);
  s->capacity = std::max<size_t>(1, capacity);
  s->wake = std::move(wake);
  bool closed;
  {
    std::lock_guard<std::mutex> lock(mu_);
    s->closed = closed = closed_;
    subs_.push_back(s);
  }
  if (closed && s->wake) s->wake();
  return s;
}

void ResultsHub::unsubscribe(const std::shared_ptr<Subscription>& s) {
  std::lock_guard<std::mutex> lock(mu_);
  subs_.erase(std::remove(subs_.begin(), subs_.end(), s), subs_.end());
}

void ResultsHub::publish(const StoredFillet& f) {
  std::vector<std::shared_ptr<Subscription>> woken;
  const auto shared = std::make_shared<const StoredFillet>(f);
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& s : subs_) {
      if (!s->lanes.empty() && !s->lanes.count(f.lane)) continue;
      if (!s->decisions.empty() && !s->decisions.count(f.decision)) continue;
      if (s->queue.size() >= s->capacity) {
        s->queue.pop_front();  // the slow subscriber loses its oldest, and is told
        ++s->lagged;
      }
      s->queue.push_back(shared);
      if (s->wake) woken.push_back(s);
    }
  }
  for (auto& s : woken) s->wake();
}

bool ResultsHub::take(const std::shared_ptr<Subscription>& s, StoredFillet& out, uint64_t& lagged) {
  std::shared_ptr<const StoredFillet> next;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (s->queue.empty()) return false;
    next = std::move(s->queue.front());
    s->queue.pop_front();
    lagged = s->lagged;
    s->lagged = 0;
  }
  out = *next;  // copied outside the lock: the publisher does not wait on it
  return true;
}

uint64_t ResultsHub::backlog(const std::shared_ptr<Subscription>& s) {
  std::lock_guard<std::mutex> lock(mu_);
  return s->queue.size() + s->lagged;
}

bool ResultsHub::closed(const std::shared_ptr<Subscription>& s) {
  std::lock_guard<std::mutex> lock(mu_);
  return s->closed;
}

void ResultsHub::close_all() {
  std::vector<std::shared_ptr<Subscription>> woken;
  {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
    for (auto& s : subs_) {
      s->closed = true;
      if (s->wake) woken.push_back(s);
    }
  }
  for (auto& s : woken) s->wake();
}

int ResultsHub::subscribers() {
  std::lock_guard<std::mutex> lock(mu_);
  return int(subs_.size());
}

}  // namespace rangex
