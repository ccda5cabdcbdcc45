// Fan-out of fillet results to live subscribers (dashboards). Every subscriber has its own
// bounded queue: a slow one loses its oldest results and is told how many, and never holds
// up the line.
#pragma once
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

#include "service/store.h"

namespace rangex {

class ResultsHub {
 public:
  struct Subscription {
    std::set<int> lanes;              // empty: all
    std::set<std::string> decisions;  // empty: all
    size_t capacity = 256;
    std::deque<StoredFillet> queue;
    uint64_t lagged = 0;  // dropped since the last delivery
    bool closed = false;
  };

  std::shared_ptr<Subscription> subscribe(std::set<int> lanes, std::set<std::string> decisions,
                                          size_t capacity = 256);
  void unsubscribe(const std::shared_ptr<Subscription>& s);
  void publish(const StoredFillet& f);
  // Waits up to `timeout_ms` for a result; returns false on timeout or when closed.
  bool next(const std::shared_ptr<Subscription>& s, int timeout_ms, StoredFillet& out,
            uint64_t& lagged);
  void close_all();  // shutdown: wakes every waiting subscriber
  int subscribers();

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::shared_ptr<Subscription>> subs_;
};

}  // namespace rangex
