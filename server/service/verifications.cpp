#include "service/verifications.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "core/error.h"
#include "core/log.h"
#include "core/size_limits.h"

namespace rangex {

namespace {

int64_t unix_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

Verifications::Verifications(const PlantConfig& plant, Store& store)
    : plant_(plant), store_(store) {
  // The audit's details begin "lane L: "; the newest result of each lane wins.
  for (const AuditEntry& e : store_.audit_entries_of("verification.", 100000)) {
    if (e.what != "verification.pass" && e.what != "verification.fail") continue;
    int lane = -1;
    if (std::sscanf(e.detail.c_str(), "lane %d:", &lane) != 1) continue;
    VerificationResult r;
    r.passed = e.what == "verification.pass";
    r.who = e.who;
    r.unix_ns = e.ts_ns;
    r.detail = e.detail;
    const auto q0 = e.detail.find('\''), q1 = e.detail.find('\'', q0 + 1);
    if (q0 != std::string::npos && q1 != std::string::npos)
      r.piece = e.detail.substr(q0 + 1, q1 - q0 - 1);
    last_[lane] = r;
  }
}

void Verifications::start(const VerificationRequest& in, const std::string& who) {
  VerificationRequest req = in;
  plant_.lane(req.lane);  // NotFound for an unknown lane
  check_name("the test piece's name", req.piece, 200);
  if (req.piece.find('\'') != std::string::npos)
    fail("the test piece's name holds a quote (name it e.g. 2 mm calcified sphere)");
  if (!std::isfinite(req.x_mm) || std::fabs(req.x_mm) > 2000)
    fail("x_mm ", req.x_mm, " is not a place across the belt");
  if (req.tolerance_mm == 0) req.tolerance_mm = plant_.verification.tolerance_mm;
  if (req.fillets == 0) req.fillets = plant_.verification.fillets;
  if (!(req.tolerance_mm > 0 && req.tolerance_mm < 500))
    fail("tolerance_mm must be between 0 and 500");
  if (req.fillets < 1 || req.fillets > 1000) fail("fillets must be 1..1000");
  {
    std::lock_guard<std::mutex> lk(mu_);
    const auto it = running_.find(req.lane);
    if (it != running_.end())
      throw FailedPrecondition(join("lane ", req.lane, " is verifying '", it->second.req.piece,
                                    "' (", it->second.left, " fillets to go)"));
    running_[req.lane] = Running{req, who, req.fillets};
  }
  store_.audit(who, "verification.start",
               join("lane ", req.lane, ": '", req.piece, "' at x ", req.x_mm, " mm (+-",
                    req.tolerance_mm, " mm), within the next ", req.fillets, " fillets"));
}

void Verifications::finish(int lane, const Running& run, bool passed, const StoredFillet* f,
                           double found) {
  VerificationResult r;
  r.piece = run.req.piece;
  r.who = run.who;
  r.x_mm = run.req.x_mm;
  r.passed = passed;
  r.unix_ns = unix_now_ns();
  r.fillet_uid = f ? f->uid : 0;
  r.found_x_mm = found;
  r.detail =
      passed ? join("lane ", lane, ": '", r.piece, "' declared at x ", r.x_mm, " mm, shown at x ",
                    found, " mm in fillet ", f->uid, " (images/", f->uid, ")")
             : join("lane ", lane, ": '", r.piece, "' declared at x ", r.x_mm,
                    " mm, not shown within ", run.req.tolerance_mm, " mm in ", run.req.fillets,
                    " fillets");
  store_.audit(run.who, passed ? "verification.pass" : "verification.fail", r.detail);
  if (passed)
    log::info("verification_pass", "{}", r.detail);
  else
    log::warn("verification_fail", "{}", r.detail);
  last_[lane] = r;
}

void Verifications::decided(const StoredFillet& f) {
  std::lock_guard<std::mutex> lk(mu_);
  const auto it = running_.find(f.lane);
  if (it == running_.end()) return;
  Running& run = it->second;
  // The piece is shown when a bone fragment lies where it was declared, on a fillet that was
  // inspected: one not inspected names the bone found where it had thickness, but a lane
  // whose fillets go uninspected is not shown to inspect.
  const bool inspected = f.decision == "reject";
  for (const StoredFragment& g : f.fragments)
    if (inspected && g.kind == "bone" && std::fabs(g.x_mm - run.req.x_mm) <= run.req.tolerance_mm) {
      const Running done = run;
      running_.erase(it);
      finish(f.lane, done, true, &f, g.x_mm);
      return;
    }
  if (--run.left > 0) return;
  const Running done = run;
  running_.erase(it);
  finish(f.lane, done, false, nullptr, 0);
}

LaneVerification Verifications::lane(int lane) const {
  std::lock_guard<std::mutex> lk(mu_);
  LaneVerification v;
  const auto l = last_.find(lane);
  if (l != last_.end()) v.last = l->second;
  const auto r = running_.find(lane);
  if (r != running_.end()) {
    v.running = true;
    v.running_piece = r->second.req.piece;
    v.fillets_left = r->second.left;
  }
  const double every = plant_.verification.every_h;
  const double age_h = v.last ? double(unix_now_ns() - v.last->unix_ns) / 3.6e12 : 1e9;
  v.overdue = (v.last && !v.last->passed) || (every > 0 && age_h > every);
  return v;
}

}  // namespace rangex
