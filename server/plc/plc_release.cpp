#include "plc/plc_release.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/error.h"
#include "core/log.h"
#include "plc/modbus_link.h"

namespace rangex {

namespace {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Informational entries (rejects, not inspected) kept while the PLC cannot be reached.
constexpr size_t kMaxQueued = 4096;

// The parts of the register map a PLC program may refuse (PlcRelease::Area), and what a
// refusal of each costs the line.
const char* area_name(int area) {
  static const char* const names[] = {"the heartbeat", "a lane's state", "the release ring",
                                      "the ring's head"};
  return names[area];
}

const char* area_cost(int area) {
  static const char* const costs[] = {
      "the PLC cannot tell that rangexd is alive", "the PLC does not see the lanes' states",
      "no fillet is released: every one is diverted", "releases are taken without it"};
  return costs[area];
}

std::string release_name(const Release& r) {
  return join("lane ", r.lane, " fillet ", r.uid, " (lines ", r.first_encoder, "..", r.last_encoder,
              ")");
}

}  // namespace

PlcRelease::PlcRelease(const PlantConfig& plant, PlcHooks hooks)
    : cfg_(plant.plc), hooks_(std::move(hooks)) {
  for (const LaneConfig& l : plant.lanes) {
    step_mm_[l.id] = l.encoder_step_mm;
    deadline_lines_[l.id] =
        int64_t(std::floor((cfg_.reject_station_mm - cfg_.margin_mm) / l.encoder_step_mm));
  }
  link_ = std::make_unique<ModbusLink>(cfg_.address, cfg_.unit_id, cfg_.timeout_ms);
  status_.enabled = true;
  status_.address = cfg_.address;
  status_.error = "not connected yet";
}

PlcRelease::~PlcRelease() {
  stop();
}

void PlcRelease::start() {
  thread_ = std::thread([this] { run(); });
}

int64_t PlcRelease::deadline(int lane, int64_t first_encoder) const {
  const auto it = deadline_lines_.find(lane);
  return first_encoder + (it == deadline_lines_.end() ? 0 : it->second);
}

void PlcRelease::decided(const Release& r) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    woken_ = true;
    queue_.push_back({r, now_ns()});
    // While the PLC cannot be reached, the oldest informational entries go first: a pass is
    // never dropped here (it is unreleased at its deadline, counted).
    if (queue_.size() > kMaxQueued) {
      const auto it = std::find_if(queue_.begin(), queue_.end(),
                                   [](const Queued& q) { return q.r.code != ReleaseCode::kPass; });
      if (it != queue_.end()) queue_.erase(it);
    }
  }
  wake_.notify_all();
}

void PlcRelease::flush(double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (queue_.empty() || !status_.connected) return;
      woken_ = true;
    }
    wake_.notify_all();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

PlcStatus PlcRelease::status() const {
  std::lock_guard<std::mutex> lk(mu_);
  PlcStatus s = status_;
  s.pending = queue_.size();
  return s;
}

void PlcRelease::stop() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (stop_ && !thread_.joinable()) return;
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  // The PLC hears that rangex stops (it diverts everything from now on).
  if (link_->connected()) {
    for (const auto& [lane, step] : step_mm_) {
      (void)step;
      const uint16_t regs[2] = {uint16_t(PackMl::kStopped), uint16_t(StateReason::kStopping)};
      try {
        link_->write(cfg_.lane_state_base + 2 * lane, regs, 2);
      } catch (const PlcRefusal& e) {  // this lane's registers: the next lane's may be mapped
        log::warn("plc_stop", "could not write lane {}'s stopped state: {}", lane, e.what());
      } catch (const std::exception& e) {  // the connection: no lane's can be written
        log::warn("plc_stop", "could not write the lanes' stopped state: {}", e.what());
        break;
      }
    }
    link_->close();
  }
}

void PlcRelease::run() {
  // A round at least every 50 ms (the lanes' states, the deadlines of what waits), and one as
  // soon as a release is decided; the heartbeat keeps its own period within them.
  const auto period =
      std::chrono::duration<double, std::milli>(std::min(cfg_.heartbeat_ms / 2, 50.0));
  while (true) {
    {
      std::unique_lock<std::mutex> lk(mu_);
      wake_.wait_for(lk, period, [this] { return stop_ || woken_; });
      woken_ = false;
      if (stop_) break;
    }
    connect_if_due();
    // The releases queued so far, then the lanes once a round: the states and the deadlines
    // read the same belt counts, read after those releases were decided. A release judged
    // on counts from before its decision could be sent as a pass when it was late; one
    // queued after this read waits for the next round's.
    size_t queued = 0;
    {
      std::lock_guard<std::mutex> lk(mu_);
      queued = queue_.size();
    }
    std::vector<PlcLaneView> lanes;
    if (hooks_.lanes) lanes = hooks_.lanes();
    heartbeat_and_states(lanes);
    send_due(lanes, queued);
  }
}

void PlcRelease::lost(const std::string& why) {
  link_->close();
  const bool was = answered_;
  answered_ = false;
  {
    std::lock_guard<std::mutex> lk(mu_);
    status_.connected = false;
    status_.error = why;
  }
  if (was) {
    log::warn("plc_lost", "{}", why);
    if (hooks_.audit) hooks_.audit("plc.lost", why);
  }
  next_connect_ns_ = now_ns() + int64_t(backoff_s_ * 1e9);
  backoff_s_ = std::min(5.0, backoff_s_ * 2);
}

void PlcRelease::connect_if_due() {
  if (link_->connected() || now_ns() < next_connect_ns_) return;
  try {
    link_->connect();
  } catch (const std::exception& e) {
    {
      std::lock_guard<std::mutex> lk(mu_);
      status_.error = e.what();
    }
    next_connect_ns_ = now_ns() + int64_t(backoff_s_ * 1e9);
    backoff_s_ = std::min(5.0, backoff_s_ * 2);
    return;
  }
  // Connected is not answering: the heartbeat at once asks the PLC.
  answered_ = false;
  next_beat_ns_ = 0;
  written_.clear();  // the PLC may have restarted: every lane's state again
}

void PlcRelease::answered() {
  if (answered_) return;
  answered_ = true;
  backoff_s_ = 0.2;
  const bool again = ever_connected_;
  ever_connected_ = true;
  {
    std::lock_guard<std::mutex> lk(mu_);
    status_.connected = true;
    status_.error.clear();
    if (again) ++status_.reconnects;
    show_refusals();
  }
  log::info("plc_connected", "PLC {} connected", cfg_.address);
  if (again && hooks_.audit) hooks_.audit("plc.connected", cfg_.address);
}

void PlcRelease::show_refusals() {
  status_.refused.clear();
  for (const auto& [area, r] : refusals_)
    status_.refused += (status_.refused.empty() ? "" : "; ") + r.why;
}

bool PlcRelease::refused(Area area) const {
  return refusals_.count(area) > 0;
}

bool PlcRelease::write(Area area, int first, const uint16_t* values, int n) {
  const int64_t t = now_ns();
  const auto it = refusals_.find(area);
  if (it != refusals_.end() && t < it->second.retry_ns) return false;
  try {
    link_->write(first, values, n);
  } catch (const PlcRefusal& e) {
    answered();  // a refusal is an answer: the connection is sound
    const bool starts = it == refusals_.end();
    Refusal& r = refusals_[area];
    r.retry_ns = t + 1'000'000'000;
    r.why = join(e.what(), " (", area_name(int(area)), "; ", area_cost(int(area)),
                 "): its program must map the registers of plant.yaml's plc section (docs/plc.md)");
    {
      std::lock_guard<std::mutex> lk(mu_);
      show_refusals();
    }
    if (starts) {
      log::warn("plc_refused", "{}", r.why);
      if (hooks_.audit) hooks_.audit("plc.refused", r.why);
    }
    return false;
  }
  answered();
  if (it != refusals_.end()) {
    refusals_.erase(it);
    {
      std::lock_guard<std::mutex> lk(mu_);
      show_refusals();
    }
    const std::string what = join(cfg_.address, ": ", area_name(int(area)), " written again");
    log::info("plc_accepted", "{}", what);
    if (hooks_.audit) hooks_.audit("plc.accepted", what);
  }
  return true;
}

void PlcRelease::heartbeat_and_states(const std::vector<PlcLaneView>& lanes) {
  if (!link_->connected()) return;
  const int64_t t = now_ns();
  try {
    if (t >= next_beat_ns_) {
      beat_ = uint16_t(beat_ == 65535 ? 1 : beat_ + 1);
      write(Area::kHeartbeat, cfg_.heartbeat_register, &beat_, 1);
      next_beat_ns_ = t + int64_t(cfg_.heartbeat_ms * 1e6);
    }
    for (const PlcLaneView& v : lanes) {
      if (v.has_count) {
        // The belt's speed from the encoder: the count now and a second or so ago.
        auto& b = belt_[v.lane];
        if (b.second == 0 || t - b.second > 1'000'000'000) b = {v.belt_count, t};
      }
      const auto want = std::make_pair(v.state, v.reason);
      const auto it = written_.find(v.lane);
      if (it != written_.end() && it->second == want) continue;
      const uint16_t regs[2] = {uint16_t(v.state), uint16_t(v.reason)};
      if (!write(Area::kLaneStates, cfg_.lane_state_base + 2 * v.lane, regs, 2)) continue;
      written_[v.lane] = want;
      std::lock_guard<std::mutex> lk(mu_);
      status_.lane_states[v.lane] = packml_name(v.state);
    }
  } catch (const std::exception& e) {
    lost(e.what());
  }
}

size_t PlcRelease::unreleased_at_deadline(const std::map<int, PlcLaneView>& views, size_t count) {
  std::vector<std::string> audits;
  {
    std::lock_guard<std::mutex> lk(mu_);
    size_t n = std::min(count, queue_.size());
    for (size_t i = 0; i < n;) {
      const Release& r = queue_[i].r;
      const auto v = views.find(r.lane);
      if (r.code != ReleaseCode::kPass || v == views.end() || !v->second.has_count ||
          v->second.belt_count < deadline(r.lane, r.first_encoder)) {
        ++i;
        continue;
      }
      audits.push_back(join(release_name(r), ": the PLC ",
                            link_->connected() ? "refused the ring's registers" : "was unreachable",
                            " until its deadline; diverted"));
      queue_.erase(queue_.begin() + long(i));
      --n;
      ++status_.unreleased;
    }
  }
  if (hooks_.audit)
    for (const std::string& a : audits) hooks_.audit("release.unreleased", a);
  return audits.size();
}

void PlcRelease::send_due(const std::vector<PlcLaneView>& lanes, size_t count) {
  std::map<int, PlcLaneView> views;
  for (const PlcLaneView& v : lanes) views[v.lane] = v;
  // A pass whose deadline passed while the PLC could not be reached, or refused the ring, is
  // never sent as a pass: counted unreleased wherever it waits, behind entries still to go.
  if (!link_->connected() || refused(Area::kRing)) count -= unreleased_at_deadline(views, count);
  if (!link_->connected()) return;
  const int64_t t = now_ns();
  for (size_t taken = 0; taken < count; ++taken) {
    Queued q;
    {
      std::lock_guard<std::mutex> lk(mu_);
      if (queue_.empty()) return;
      q = queue_.front();
    }
    const auto v = views.find(q.r.lane);
    const bool counted = v != views.end() && v->second.has_count;
    const int64_t belt = counted ? v->second.belt_count : INT64_MIN;
    const int64_t dl = deadline(q.r.lane, q.r.first_encoder);
    if (q.r.code == ReleaseCode::kPass && counted && belt >= dl) {
      q.r.code = ReleaseCode::kLate;
      {
        std::lock_guard<std::mutex> lk(mu_);
        queue_.front().r.code = ReleaseCode::kLate;
        ++status_.late;
      }
      if (hooks_.audit)
        hooks_.audit("release.late", join(release_name(q.r), ": decided at line ", belt,
                                          ", deadline ", dl, "; late: diverted"));
    }
    const SlotRegisters regs = release_registers(q.r);
    const int slot = release_slot(q.r.uid, cfg_.ring_slots);
    const int base = cfg_.ring_base + kSlotRegisters * slot;
    try {
      // The slot's fields, then its sequence (the PLC takes a slot when its sequence changes
      // and its check holds): refused, the release waits. Then the head, a hint: the slot
      // is taken without it.
      if (!write(Area::kRing, base + 1, &regs[1], kSlotRegisters - 1) ||
          !write(Area::kRing, base, &regs[0], 1))
        return;
      const uint16_t head = uint16_t(slot);
      write(Area::kRingHead, cfg_.ring_head_register, &head, 1);
    } catch (const std::exception& e) {
      lost(e.what());
      return;
    }
    std::lock_guard<std::mutex> lk(mu_);
    queue_.pop_front();
    if (q.r.code == ReleaseCode::kPass) {
      ++status_.released;
      const auto b = belt_.find(q.r.lane);
      if (counted && b != belt_.end() && t > b->second.second && belt > b->second.first) {
        const double lines_per_s = double(belt - b->second.first) / ((t - b->second.second) / 1e9);
        const double spare_ms = 1e3 * double(dl - belt) / lines_per_s;
        if (status_.least_spare_ms < 0 || spare_ms < status_.least_spare_ms)
          status_.least_spare_ms = spare_ms;
      }
    } else if (q.r.code != ReleaseCode::kLate) {
      ++status_.diverted;
    }
  }
}

}  // namespace rangex
