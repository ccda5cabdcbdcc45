// Positive release to a PLC over Modbus TCP: rangex's writer against a simulated PLC (a
// libmodbus server in the test) whose belts the test moves.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <mutex>
#include <thread>

#include "core/plant_config.h"
#include "plc/plc_release.h"
#include "plc/plc_simulator.h"
#include "wait_until.h"

using namespace rangex;
using namespace rangex::test;

namespace {

// Two lanes of 0.4 mm lines, a gate 400 mm (1000 lines) past the X-ray plane, releases due
// 20 mm (50 lines) before it: a fillet starting at line F is due by line F + 950.
struct Rig {
  PlantConfig plant = default_plant_config(2);
  std::unique_ptr<SimPlc> plc;
  std::mutex mu;
  std::map<int, int64_t> belt;  // lane: encoder count now
  std::vector<std::pair<std::string, std::string>> audit;
  std::unique_ptr<PlcRelease> release;

  explicit Rig(double heartbeat_ms = 20) {
    plant.plc.reject_station_mm = 400;
    plant.plc.margin_mm = 20;
    plant.plc.heartbeat_ms = heartbeat_ms;
    plant.plc.timeout_ms = 200;
    plc = std::make_unique<SimPlc>(plant.plc);
    plant.plc.address = "127.0.0.1:" + std::to_string(plc->port());
    PlcHooks hooks;
    hooks.lanes = [this] {
      std::lock_guard<std::mutex> lk(mu);
      std::vector<PlcLaneView> v;
      for (const auto& [lane, count] : belt) {
        PlcLaneView l;
        l.lane = lane;
        l.has_count = true;
        l.belt_count = count;
        l.state = PackMl::kExecute;
        l.reason = StateReason::kNone;
        v.push_back(l);
      }
      return v;
    };
    hooks.audit = [this](const std::string& what, const std::string& detail) {
      std::lock_guard<std::mutex> lk(mu);
      audit.emplace_back(what, detail);
    };
    move(0, 0);
    move(1, 0);
    release = std::make_unique<PlcRelease>(plant, hooks);
    release->start();
  }
  void move(int lane, int64_t count) {
    {
      std::lock_guard<std::mutex> lk(mu);
      belt[lane] = count;
    }
    plc->belt(lane, count);
  }
  int audited(const std::string& what) {
    std::lock_guard<std::mutex> lk(mu);
    int n = 0;
    for (const auto& a : audit) n += a.first == what;
    return n;
  }
  static Release fillet(int64_t uid, int lane, int64_t first, ReleaseCode code) {
    return Release{uid, lane, first, first + 400, code};
  }
};

}  // namespace

TEST(PlcRelease, RegistersRoundTripAndAWrongCheckIsRefused) {
  const Release r{70001, 3, 123456789, 123457189, ReleaseCode::kReject};
  SlotRegisters s = release_registers(r);
  Release back;
  uint16_t seq = 0;
  ASSERT_TRUE(decode_release(s, back, seq));
  EXPECT_EQ(seq, release_sequence(70001));
  EXPECT_EQ(back.lane, 3);
  EXPECT_EQ(back.first_encoder, 123456789);
  EXPECT_EQ(back.last_encoder, 123457189);
  EXPECT_EQ(back.code, ReleaseCode::kReject);
  s[4] ^= 1;  // a slot half written
  EXPECT_FALSE(decode_release(s, back, seq));
  // Sequences never take 0 ("nothing written") and rise with the uid across the wrap.
  EXPECT_EQ(release_sequence(65535), 65535);
  EXPECT_EQ(release_sequence(65536), 1);
  EXPECT_NE(release_slot(5, 64), release_slot(6, 64));
}

TEST(PlcRelease, CleanFilletsInTimeAreReleasedAndTheRestDiverted) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.move(0, 500);
  rig.move(1, 500);
  rig.release->decided(Rig::fillet(1, 0, 100, ReleaseCode::kPass));  // due by 1050
  rig.release->decided(Rig::fillet(2, 1, 120, ReleaseCode::kReject));
  rig.release->decided(Rig::fillet(3, 0, 300, ReleaseCode::kNotInspected));
  // The PLC takes a slot on its sequence's write; the release counts it after the head's, so
  // wait for both (on a busy machine the test read the counts in between).
  ASSERT_TRUE(wait_until(
      10, [&] { return rig.plc->received().size() == 3 && rig.release->status().pending == 0; }));
  const auto got = rig.plc->received();
  EXPECT_EQ(got[0].release.code, ReleaseCode::kPass);
  EXPECT_EQ(got[0].release.first_encoder, 100);
  EXPECT_EQ(got[0].release.last_encoder, 500);
  EXPECT_LT(got[0].belt, 100 + 950);  // arrived before its deadline
  EXPECT_EQ(got[1].release.code, ReleaseCode::kReject);
  EXPECT_EQ(got[1].release.lane, 1);
  EXPECT_EQ(got[2].release.code, ReleaseCode::kNotInspected);
  const PlcStatus s = rig.release->status();
  EXPECT_EQ(s.released, 1u);
  EXPECT_EQ(s.diverted, 2u);
  EXPECT_EQ(s.late + s.unreleased, 0u);
  // The heartbeat counts and the lanes' states are written.
  const uint16_t beat = rig.plc->heartbeat();
  EXPECT_TRUE(wait_until(5, [&] { return rig.plc->heartbeat() != beat; }));
  EXPECT_EQ(rig.plc->lane_state(1), PackMl::kExecute);
  EXPECT_EQ(s.lane_states.at(0), "execute");
}

// The writer's round is not the heartbeat's: a plant that beats once a minute still has each
// release sent as it is decided, and its lanes' states written at once.
TEST(PlcRelease, AReleaseIsSentWhenDecidedNotAtTheNextHeartbeat) {
  Rig rig(60000);
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  EXPECT_TRUE(wait_until(10, [&] { return rig.plc->lane_state(1) == PackMl::kExecute; }));
  rig.release->decided(Rig::fillet(41, 0, 100, ReleaseCode::kPass));
  // Counted after the head's write: wait for both.
  ASSERT_TRUE(wait_until(
      10, [&] { return rig.plc->received().size() == 1 && rig.release->status().pending == 0; }));
  EXPECT_EQ(rig.release->status().released, 1u);
}

TEST(PlcRelease, APassDecidedAfterItsDeadlineIsSentAsLateAndAudited) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.move(0, 1100);  // past 100 + 950
  rig.release->decided(Rig::fillet(7, 0, 100, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return rig.plc->received().size() == 1; }));
  EXPECT_EQ(rig.plc->received()[0].release.code, ReleaseCode::kLate);
  EXPECT_EQ(rig.release->status().late, 1u);
  EXPECT_EQ(rig.release->status().released, 0u);
  EXPECT_EQ(rig.audited("release.late"), 1);
}

TEST(PlcRelease, AnUnreachablePlcReleasesNothingAndCountsWhatItCouldNot) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.plc->stop();  // the PLC goes away (and comes back without its registers)
  rig.release->decided(Rig::fillet(11, 0, 100, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return !rig.release->status().connected; }));
  EXPECT_FALSE(rig.release->status().error.empty());
  rig.move(0, 1060);  // its deadline passes while the PLC is away
  // The count comes before its audit entry is written: wait for both.
  ASSERT_TRUE(wait_until(10, [&] {
    return rig.release->status().unreleased == 1 && rig.audited("release.unreleased") == 1;
  }));
  EXPECT_EQ(rig.audited("plc.lost"), 1);
  rig.plc->start();
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.release->decided(Rig::fillet(12, 0, 1000, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return rig.plc->received().size() == 1; }));
  // Only the new fillet: the one that was due while the PLC was away is never sent as a pass.
  EXPECT_EQ(rig.plc->received()[0].release.first_encoder, 1000);
  EXPECT_EQ(rig.release->status().reconnects, 1u);
  EXPECT_EQ(rig.audited("plc.connected"), 1);
  // A restarted PLC has its lanes' states written again.
  EXPECT_TRUE(wait_until(5, [&] { return rig.plc->lane_state(0) == PackMl::kExecute; }));
}

// While the PLC is away a reject waits at the queue's head to be sent; a pass behind it whose
// deadline passes is counted unreleased then, not sent late once the PLC is back.
TEST(PlcRelease, APassBehindAWaitingRejectIsUnreleasedAtItsDeadline) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.plc->stop();
  rig.release->decided(Rig::fillet(51, 1, 100, ReleaseCode::kReject));
  rig.release->decided(Rig::fillet(52, 0, 100, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return !rig.release->status().connected; }));
  rig.move(0, 1060);  // the pass's deadline passes while the PLC is away
  ASSERT_TRUE(wait_until(10, [&] {
    return rig.release->status().unreleased == 1 && rig.audited("release.unreleased") == 1;
  }));
  EXPECT_EQ(rig.release->status().pending, 1u);  // the reject, still to be sent
  rig.plc->start();
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().pending == 0; }));
  ASSERT_EQ(rig.plc->received().size(), 1u);
  EXPECT_EQ(rig.plc->received()[0].release.code, ReleaseCode::kReject);
  EXPECT_EQ(rig.release->status().late, 0u);
}

TEST(PlcRelease, APlcRestartedMidRunGetsEveryLaterReleaseOnce) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  int64_t uid = 0;
  for (int k = 0; k < 20; ++k)
    rig.release->decided(Rig::fillet(++uid, k % 2, 100 + k, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return rig.plc->received().size() == 20; }));
  rig.plc->stop();
  rig.plc->start();
  for (int k = 0; k < 100; ++k)
    rig.release->decided(Rig::fillet(++uid, k % 2, 200 + k, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(20, [&] { return rig.release->status().pending == 0; }));
  std::map<int64_t, int> times;  // (lane, first) released how often
  for (const auto& r : rig.plc->received())
    ++times[r.release.lane * 1000000 + r.release.first_encoder];
  int twice = 0;
  for (const auto& [k, n] : times) twice += n > 1;
  EXPECT_EQ(twice, 0);
  // Everything decided after the restart reached the PLC (the ring holds 64: it was read
  // as it was written).
  int after = 0;
  for (const auto& r : rig.plc->received()) after += r.release.first_encoder >= 200;
  EXPECT_EQ(after, 100);
  EXPECT_EQ(rig.release->status().released, 120u);
}

// A PLC program whose map ends before the ring answers each release with exception 2. The
// connection is sound: it is one refusal, named, not a PLC lost and found again each round.
TEST(PlcRelease, APlcThatRefusesTheRingIsNamedOnceAndReleasesNothing) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.plc->set_registers(100);  // the heartbeat and lane states (0..139) only in part
  rig.release->decided(Rig::fillet(21, 0, 100, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return rig.audited("plc.refused") == 1; }));
  const PlcStatus refused = rig.release->status();
  EXPECT_TRUE(refused.connected);
  EXPECT_TRUE(refused.error.empty()) << refused.error;
  // Which registers (uid 21's slot), the part of the map, what it costs, and where to look.
  for (const char* said :
       {"refuses registers 369..375", "release ring", "every one is diverted", "plant.yaml"})
    EXPECT_NE(refused.refused.find(said), std::string::npos) << said << ": " << refused.refused;
  rig.move(0, 1060);  // its deadline passes while the PLC refuses it
  ASSERT_TRUE(wait_until(10, [&] {
    return rig.release->status().unreleased == 1 && rig.audited("release.unreleased") == 1;
  }));
  EXPECT_EQ(rig.release->status().late, 0u);  // never sent, so not sent late
  // A window of rounds: the refusal is not a loss, and it is audited once.
  const uint16_t beat = rig.plc->heartbeat();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  EXPECT_NE(rig.plc->heartbeat(), beat);  // register 0 is mapped: rangexd's heartbeat goes on
  EXPECT_EQ(rig.audited("plc.refused"), 1);
  EXPECT_EQ(rig.audited("plc.lost"), 0);
  EXPECT_EQ(rig.audited("plc.connected"), 0);
  EXPECT_EQ(rig.release->status().reconnects, 0u);
  EXPECT_TRUE(rig.plc->received().empty());
  EXPECT_EQ(rig.release->status().pending, 0u);
  // The PLC program mended: the next release reaches it, and the refusal is over.
  rig.plc->set_registers(65536);
  rig.release->decided(Rig::fillet(22, 0, 2000, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(
      10, [&] { return rig.plc->received().size() == 1 && rig.release->status().pending == 0; }));
  EXPECT_EQ(rig.plc->received()[0].release.first_encoder, 2000);
  ASSERT_TRUE(wait_until(10, [&] { return rig.audited("plc.accepted") == 1; }));
  EXPECT_TRUE(rig.release->status().refused.empty()) << rig.release->status().refused;
  EXPECT_EQ(rig.release->status().released, 1u);
}

// A PLC that takes the connection and answers nothing: each reconnect succeeds and its first
// write times out. That is one loss, retried with a growing backoff, until it answers again.
TEST(PlcRelease, APlcThatStopsAnsweringIsLostOnceWhileItIsRetried) {
  Rig rig;
  ASSERT_TRUE(wait_until(10, [&] { return rig.release->status().connected; }));
  rig.plc->set_silent(true);
  ASSERT_TRUE(wait_until(10, [&] { return rig.audited("plc.lost") == 1; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));  // several reconnects
  const PlcStatus silent = rig.release->status();
  EXPECT_FALSE(silent.connected);
  EXPECT_NE(silent.error.find("timed out"), std::string::npos) << silent.error;
  EXPECT_EQ(rig.audited("plc.lost"), 1);
  EXPECT_EQ(rig.audited("plc.connected"), 0);
  EXPECT_EQ(silent.reconnects, 0u);
  rig.plc->set_silent(false);
  // The status comes before its audit entry is written: wait for both.
  ASSERT_TRUE(wait_until(
      15, [&] { return rig.release->status().connected && rig.audited("plc.connected") == 1; }));
  EXPECT_EQ(rig.release->status().reconnects, 1u);
  rig.release->decided(Rig::fillet(31, 1, 100, ReleaseCode::kPass));
  ASSERT_TRUE(wait_until(10, [&] { return rig.plc->received().size() == 1; }));
}
