// Verification runs (HACCP 9 CFR 417.4): an operator declares a test piece on a lane (e.g. a
// 2 mm calcified sphere) and where across the belt it was placed; the lane's next fillets or
// test cards must show a bone fragment there, within the tolerance. Pass or fail is recorded
// in the chained audit with who started it, when, and the fillet whose images show it. Each
// lane's last result is kept (read back from the audit at start), and a lane is overdue once
// plant.yaml's every_h has passed since it.
#pragma once
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>

#include "core/plant_config.h"
#include "store/store.h"

namespace rangex {

struct VerificationRequest {
  int lane = 0;
  std::string piece;        // what was placed, e.g. "2 mm calcified sphere"
  double x_mm = 0;          // where across the belt (the lane's x, as fragments report it)
  double tolerance_mm = 0;  // 0: plant.yaml's
  int fillets = 0;          // 0: plant.yaml's
};

struct VerificationResult {
  std::string piece, who;
  double x_mm = 0;
  bool passed = false;
  int64_t unix_ns = 0;
  int64_t fillet_uid = 0;  // the fillet that showed it (its images in the store)
  double found_x_mm = 0;
  std::string detail;
};

struct LaneVerification {
  std::optional<VerificationResult> last;
  bool running = false;
  std::string running_piece;
  int fillets_left = 0;
  // With a schedule (verification.every_h): never verified, or the last longer ago than
  // every_h; with or without one: the last failed.
  bool overdue = false;
};

class Verifications {
 public:
  // Each lane's last result, read from the store's audit.
  Verifications(const PlantConfig& plant, Store& store);
  // Throws Error for a bad request, FailedPrecondition while the lane runs one.
  void start(const VerificationRequest& req, const std::string& who);
  // Each decided fillet (under the decision recorder's lock; only memory and the audit).
  void decided(const StoredFillet& f);
  LaneVerification lane(int lane) const;

 private:
  struct Running {
    VerificationRequest req;
    std::string who;
    int left = 0;
  };
  void finish(int lane, const Running& run, bool passed, const StoredFillet* f, double found);

  const PlantConfig plant_;
  Store& store_;
  mutable std::mutex mu_;  // leaf
  std::map<int, Running> running_;
  std::map<int, VerificationResult> last_;
};

}  // namespace rangex
