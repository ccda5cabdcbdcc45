// Lines waiting for the worker, one queue per lane, taken round-robin: a lane's lines wait
// behind its own backlog and at most one line of each other lane per turn, never behind a
// full queue of another lane's lines. Each lane's lines keep their order. Not thread-safe:
// the engine holds its admission lock around every call.
#pragma once
#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include "core/incoming_line.h"

namespace rangex {

class LaneQueues {
 public:
  explicit LaneQueues(size_t lanes) : queues_(lanes) {}

  void push(size_t lane, QueuedLine&& q) {
    queues_[lane].push_back(std::move(q));
    ++size_;
  }
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

  // Up to `n` lines into `out`, one from each lane with lines in turn, starting after the
  // lane the previous call ended on.
  void take(size_t n, std::vector<QueuedLine>& out) {
    const size_t L = queues_.size();
    while (n > 0 && size_ > 0) {
      next_ = (next_ + 1) % L;
      std::deque<QueuedLine>& q = queues_[next_];
      if (q.empty()) continue;
      out.push_back(std::move(q.front()));
      q.pop_front();
      --size_;
      --n;
    }
  }

  // Arrival of the line that has waited longest (0: none waiting).
  int64_t oldest_arrival_ns() const {
    int64_t oldest = 0;
    for (const auto& q : queues_)
      if (!q.empty() && (oldest == 0 || q.front().arrived_ns < oldest))
        oldest = q.front().arrived_ns;
    return oldest;
  }

 private:
  std::vector<std::deque<QueuedLine>> queues_;
  size_t size_ = 0;
  size_t next_ = 0;
};

}  // namespace rangex
