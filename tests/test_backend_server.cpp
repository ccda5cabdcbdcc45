// The server and the offline tools on every backend give the CPU's decisions: a two-lane
// recording streamed through rangexd's services with every batch verified on the CPU, the
// same with the device failing mid-stream (no line lost, the server goes on on the CPU), and
// the simulated four-lane plant of `rangexctl process --simulate --backend X`.
#include <gtest/gtest.h>

#include <algorithm>

#include "backend_cases.h"
#include "offline/plant_run.h"
#include "offline/replay.h"
#include "server_client.h"
#include "sim/plant_simulator.h"
#include "temp_dir.h"

using namespace rangex;
using namespace rangex::test;

namespace {

class ServerOn : public ::testing::TestWithParam<std::string> {
 protected:
  // A backend this machine cannot start is skipped, or fails where it is required.
  bool available() {
    for (const BackendProbe& p : probe_backends())
      if (p.name == GetParam() && p.available) return true;
    if (required(GetParam())) ADD_FAILURE() << GetParam() << " is required here";
    return false;
  }
};

#define SKIP_UNLESS_AVAILABLE() \
  if (!available()) GTEST_SKIP() << GetParam() << " cannot start on this machine"

struct Served {
  std::vector<StoredFillet> fillets;
  EngineStats stats;
};

Served serve(const PlantConfig& p, const std::vector<pb::LineScan>& lines, BackendRequest req,
             double verify, const TempDir& t, const std::string& name) {
  ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.data_dir = t.str(name);
  o.engine.backend = req;
  o.engine.verify_fraction = verify;
  o.engine.batch_lines = 32;
  // The stream below does not follow its credit: the queue holds the whole recording.
  o.engine.queue_lines = lines.size() + 64;
  Served s;
  RangexServer server(p, o);
  const auto acks = stream(connect(server), lines);
  EXPECT_EQ(acks.size(), lines.size());
  for (const auto& a : acks) EXPECT_TRUE(a.accepted()) << a.error().message();
  server.shutdown();
  s.fillets = all_fillets(server.store());
  s.stats = server.engine().stats();
  return s;
}

// Lane by lane: each lane's decisions are stored in order, lanes' among each other in the
// order their inspections finish.
std::vector<StoredFillet> by_lane(std::vector<StoredFillet> v) {
  std::stable_sort(v.begin(), v.end(),
                   [](const StoredFillet& a, const StoredFillet& b) { return a.lane < b.lane; });
  return v;
}

void expect_same_decisions(const std::vector<StoredFillet>& got_stored,
                           const std::vector<StoredFillet>& want_stored) {
  const std::vector<StoredFillet> got = by_lane(got_stored), want = by_lane(want_stored);
  ASSERT_EQ(got.size(), want.size());
  for (size_t i = 0; i < got.size(); ++i) {
    SCOPED_TRACE("fillet " + std::to_string(i));
    EXPECT_EQ(got[i].lane, want[i].lane);
    EXPECT_EQ(got[i].first_encoder, want[i].first_encoder);
    EXPECT_EQ(got[i].decision, want[i].decision);
    EXPECT_NEAR(got[i].beta1, want[i].beta1, 1e-6 * std::fabs(want[i].beta1) + 1e-9);
    ASSERT_EQ(got[i].fragments.size(), want[i].fragments.size());
    for (size_t k = 0; k < got[i].fragments.size(); ++k) {
      EXPECT_EQ(got[i].fragments[k].kind, want[i].fragments[k].kind);
      EXPECT_NEAR(got[i].fragments[k].x_mm, want[i].fragments[k].x_mm, 0.05);
      EXPECT_NEAR(got[i].fragments[k].y_mm, want[i].fragments[k].y_mm, 0.05);
    }
  }
}

// A two-lane recording (two fillets each), once per test binary.
struct Recording {
  TempDir dir;
  PlantConfig plant = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  std::vector<pb::LineScan> lines;
  Recording() {
    sim::SimulationParams sp;
    sp.lanes = 2;
    sp.scene.fillets = 2;
    sp.seed = 5;
    sim::simulate_recording(plant, sp, dir.str("rec"));
    lines = recording_lines(RecordingReader(dir.str("rec")), plant);
  }
};
const Recording& recording() {
  static const Recording r;
  return r;
}
const std::vector<StoredFillet>& cpu_decisions() {
  static const std::vector<StoredFillet> d = [] {
    TempDir t;
    return serve(recording().plant, recording().lines, cpu_request(), 0, t, "cpu").fillets;
  }();
  return d;
}

TEST_P(ServerOn, DecisionsEqualTheCpusWithEveryBatchVerified) {
  SKIP_UNLESS_AVAILABLE();
  TempDir t;
  BackendRequest req;
  req.name = GetParam();
  const Served s = serve(recording().plant, recording().lines, req, 1.0, t, "x");
  ASSERT_GE(cpu_decisions().size(), 4u);
  expect_same_decisions(s.fillets, cpu_decisions());
  EXPECT_EQ(s.stats.backend.name, GetParam());
  EXPECT_EQ(s.stats.processed, recording().lines.size());
  EXPECT_GT(s.stats.batches.batches, 0u);
  EXPECT_EQ(s.stats.batches.verified, GetParam() == "cpu" ? 0 : s.stats.batches.batches);
  EXPECT_EQ(s.stats.batches.mismatches, 0u);
  EXPECT_EQ(s.stats.batches.failures, 0u);
}

TEST_P(ServerOn, ADeviceLostMidStreamLosesNoLineAndTheServerGoesOnOnTheCpu) {
  SKIP_UNLESS_AVAILABLE();
  TempDir t;
  BackendRequest req;
  req.name = GetParam();
  req.fail_after = 5;
  const Served s = serve(recording().plant, recording().lines, req, 0.01, t, "x");
  expect_same_decisions(s.fillets, cpu_decisions());
  EXPECT_EQ(s.stats.backend.name, "cpu");
  EXPECT_NE(s.stats.backend_note.find("failed"), std::string::npos) << s.stats.backend_note;
  EXPECT_EQ(s.stats.batches.failures, 1u);
  EXPECT_EQ(s.stats.processed, recording().lines.size());
  EXPECT_TRUE(s.stats.dropped.empty());
}

TEST_P(ServerOn, WrongDeviceResultsAreCaughtAndDecidedFromTheCpu) {
  SKIP_UNLESS_AVAILABLE();
  TempDir t;
  BackendRequest req;
  req.name = GetParam();
  req.corrupt_after = 0;
  const Served s = serve(recording().plant, recording().lines, req, 1.0, t, "x");
  expect_same_decisions(s.fillets, cpu_decisions());
  EXPECT_GT(s.stats.batches.mismatches, 0u);
  EXPECT_EQ(s.stats.batches.mismatches, s.stats.batches.verified);
}

// `rangexctl process --simulate --lanes 4 --backend X`: the same run as the CLI's.
TEST_P(ServerOn, SimulatedFourLanePlantDecidesAsOnTheCpu) {
  SKIP_UNLESS_AVAILABLE();
  const PlantConfig plant = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  sim::SimulationParams sp;
  sp.lanes = 4;
  sp.scene.fillets = 2;
  sp.seed = 9;
  PlantRunOptions cpu, dev;
  dev.backend.name = GetParam();
  BackendInfo ran;
  const auto want = run_simulated_plant(plant, sp, cpu);
  const auto got = run_simulated_plant(plant, sp, dev, {}, &ran);
  EXPECT_EQ(ran.name, GetParam());
  ASSERT_EQ(got.size(), want.size());
  for (size_t l = 0; l < got.size(); ++l) {
    const RecordSet &g = got[l].ours, &w = want[l].ours;
    ASSERT_EQ(g.fillets.size(), w.fillets.size()) << "lane " << l;
    for (size_t i = 0; i < g.fillets.size(); ++i) {
      EXPECT_EQ(g.fillets[i].decision, w.fillets[i].decision) << "lane " << l << " fillet " << i;
      EXPECT_EQ(g.fillets[i].fragments, w.fillets[i].fragments);
      EXPECT_EQ(g.fillets[i].first_line, w.fillets[i].first_line);
    }
    ASSERT_EQ(g.fragments.size(), w.fragments.size()) << "lane " << l;
    for (size_t i = 0; i < g.fragments.size(); ++i) {
      EXPECT_NEAR(g.fragments[i].x_mm, w.fragments[i].x_mm, 0.05);
      EXPECT_NEAR(g.fragments[i].y_mm, w.fragments[i].y_mm, 0.05);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, ServerOn, ::testing::Values("cpu", "opencl", "vulkan"),
                         [](const auto& info) { return info.param; });

}  // namespace
