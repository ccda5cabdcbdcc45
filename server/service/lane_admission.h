// Which lines of one lane the server takes: counts increase; a resent line (a feeder that
// reconnected, or a second stream) is recognised as already accepted within a window of
// recent counts; a count further behind is an encoder reset, taken (auto_reset) or refused
// until the control plane resets the lane. Not thread-safe: the engine calls it under its
// admission lock, so that the check and the update are one step.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace rangex {

class LaneAdmission {
 public:
  enum class Outcome { kAccept, kDuplicate, kBackwards };
  struct Verdict {
    Outcome outcome = Outcome::kAccept;
    std::string restart;  // accepted, and the lane restarts first (why)
    std::string message;  // refused: why
  };

  LaneAdmission(int lane, int window, bool auto_reset);

  Verdict check(int64_t encoder) const;
  // Records an accepted line (after check said kAccept).
  void commit(int64_t encoder, bool restarted);
  // The next line starts the lane afresh, whatever its count.
  void request_reset(const std::string& why);
  // After a restart of the server: every count up to `durable` (within the window) was
  // taken before; a resend of one is a duplicate, the next count is new.
  void resume(int64_t durable);

  bool fed() const { return fed_; }
  int64_t last() const { return last_; }

 private:
  bool seen(int64_t encoder) const;
  void mark(int64_t encoder, bool on);
  void clear();

  int lane_;
  uint64_t window_;
  bool auto_reset_;
  bool fed_ = false;
  int64_t last_ = 0;
  std::string reset_;           // a commanded reset waiting for the next line
  std::vector<uint64_t> bits_;  // ring of accepted counts, indexed by count mod window
};

}  // namespace rangex
