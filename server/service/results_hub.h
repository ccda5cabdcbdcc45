// Fan-out of fillet results to live subscribers (dashboards, reject gates). Every
// subscriber has its own bounded queue: a slow one loses its oldest results and is told how
// many, and never holds up the line. A subscriber is woken (its `wake` runs) when a result
// arrives or the hub closes; it then takes what is queued. A result is held once, shared by
// every queue it waits in: a subscriber that stopped reading costs its queue of pointers,
// not 256 copies of results.
//
// Locking: the hub's mutex is a leaf; `wake` runs with no hub lock held, so a subscriber may
// take() from inside it.
#pragma once
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

#include "store/store.h"

namespace rangex {

class ResultsHub {
 public:
  struct Subscription {
    std::set<int> lanes;              // empty: all
    std::set<std::string> decisions;  // empty: all
    size_t capacity = 256;
    std::function<void()> wake;  // set at subscribe, never changed
    // Guarded by the hub's mutex:
    std::deque<std::shared_ptr<const StoredFillet>> queue;
    uint64_t lagged = 0;  // dropped since the last delivery
    bool closed = false;
  };

  std::shared_ptr<Subscription> subscribe(std::set<int> lanes, std::set<std::string> decisions,
                                          size_t capacity = 256, std::function<void()> wake = {});
  void unsubscribe(const std::shared_ptr<Subscription>& s);
  void publish(const StoredFillet& f);
  // The next queued result, without waiting; false when none. `lagged`: results this
  // subscriber lost before this one.
  bool take(const std::shared_ptr<Subscription>& s, StoredFillet& out, uint64_t& lagged);
  bool closed(const std::shared_ptr<Subscription>& s);
  // Results this subscriber has not taken: those queued and those it lost. What makes a
  // stream the one that gives way when its server has no room for a new one.
  uint64_t backlog(const std::shared_ptr<Subscription>& s);
  void close_all();  // shutdown: every subscriber is woken and sees closed once drained
  int subscribers();
  // Subscribers that fell behind and gave way to a newer one (counted by whoever let go).
  void note_dropped() { ++dropped_; }
  uint64_t dropped() const { return dropped_; }

 private:
  std::mutex mu_;
  std::vector<std::shared_ptr<Subscription>> subs_;
  bool closed_ = false;
  std::atomic<uint64_t> dropped_{0};
};

}  // namespace rangex
