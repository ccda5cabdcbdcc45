// The server's line stages on every backend: batches of mixed lanes come back in order with
// the CPU reference's results; verification on the CPU catches a backend that computes wrong
// results and replaces them; a backend that fails mid-stream has its batches in flight
// recomputed on the CPU and the runner stays there, losing no line. Failures and wrong
// results are injected into the backend under test (FaultInjectingBackend) after N batches.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "backend_cases.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/stage_runner.h"

using namespace rangex;
using namespace rangex::test;

namespace {

// Lines as the engine queues them, numbered by their encoder.
std::vector<QueuedLine> queued(const SimLines& s, const std::vector<LaneConfig>& lanes,
                               int64_t first_encoder) {
  const size_t frame = size_t(lanes[0].frame_width) * lanes[0].frame_height;
  std::vector<QueuedLine> out(size_t(s.lines));
  for (int k = 0; k < s.lines; ++k) {
    IncomingLine& in = out[k].line;
    in.lane = lanes[s.lane_slot[k]].id;
    in.encoder = first_encoder + k;
    in.cam0.assign(reinterpret_cast<const char*>(&s.frames[frame * 2 * k]), frame);
    in.cam1.assign(reinterpret_cast<const char*>(&s.frames[frame * (2 * k + 1)]), frame);
  }
  return out;
}

struct Received {
  std::vector<int64_t> encoders;
  std::vector<float> thickness;
  std::vector<uint8_t> valid;
};

class StageRunnerOn : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    lanes_ = three_lanes();
    batches_ = {SimLines(lanes_, 5, 160), SimLines(lanes_, 1, 200), SimLines(lanes_, 3, 230),
                SimLines(lanes_, 2, 170)};
    // What the CPU reference computes for each batch, back to back.
    const LinePipeline ref(lanes_, 1);
    int64_t enc = 0;
    for (const SimLines& b : batches_) {
      LineResults r;
      ref.run(b.frames.data(), b.lines, b.lane_slot.data(), r);
      want_.thickness.insert(want_.thickness.end(), r.thickness.begin(), r.thickness.end());
      want_.valid.insert(want_.valid.end(), r.thickness_valid.begin(), r.thickness_valid.end());
      for (int k = 0; k < b.lines; ++k) want_.encoders.push_back(enc++);
    }
  }

  // Runs every batch through a runner on the backend under test (two in flight where it
  // overlaps), with `faults` injected and `verify` of the batches verified.
  std::unique_ptr<StageRunner> run(BackendRequest req, double verify, Received& got) {
    req.name = GetParam();
    req.guards = true;
    auto sink = [&got](std::vector<QueuedLine>& lines, const LineResults& r, double) {
      for (const QueuedLine& q : lines) got.encoders.push_back(q.line.encoder);
      got.thickness.insert(got.thickness.end(), r.thickness.begin(), r.thickness.end());
      got.valid.insert(got.valid.end(), r.thickness_valid.begin(), r.thickness_valid.end());
    };
    auto lost = [](std::vector<QueuedLine>& lines, const std::string& why) {
      ADD_FAILURE() << lines.size() << " lines lost: " << why;
    };
    auto runner =
        std::make_unique<StageRunner>(lanes_, StageRunnerOptions{req, verify}, sink, lost);
    if (runner->running().name.rfind(GetParam(), 0) != 0) {
      if (required(GetParam())) {
        ADD_FAILURE() << GetParam() << " is required here: " << runner->note();
      } else {
        skipped_ = runner->note();
      }
      return nullptr;
    }
    int64_t enc = 0;
    for (const SimLines& b : batches_) {
      runner->launch(queued(b, lanes_, enc));
      enc += b.lines;
    }
    runner->finish_all();
    return runner;
  }

  void expect_reference(const Received& got) {
    ASSERT_EQ(got.encoders, want_.encoders);  // every line, once, in order
    ASSERT_EQ(got.thickness.size(), want_.thickness.size());
    size_t off = 0;
    for (size_t i = 0; i < got.thickness.size(); ++i) {
      ASSERT_EQ(got.valid[i], want_.valid[i]) << "item " << i;
      if (!got.valid[i]) continue;
      off += !(std::fabs(got.thickness[i] - want_.thickness[i]) <= 1e-3);
    }
    EXPECT_EQ(off, 0u) << "thickness items beyond 1e-3 mm of the CPU's";
  }

  std::vector<LaneConfig> lanes_;
  std::vector<SimLines> batches_;
  Received want_;
  std::string skipped_;
};

#define SKIP_IF_UNAVAILABLE(r)                       \
  if (!(r)) {                                        \
    if (!skipped_.empty()) GTEST_SKIP() << skipped_; \
    return;                                          \
  }

TEST_P(StageRunnerOn, EveryBatchVerifiedEqualsTheCpuReference) {
  Received got;
  const auto r = run({}, 1.0, got);
  SKIP_IF_UNAVAILABLE(r);
  expect_reference(got);
  const StageRunnerStats s = r->stats();
  EXPECT_EQ(s.batches, 4u);
  // The CPU backend is the reference itself: nothing to verify it against.
  EXPECT_EQ(s.verified, GetParam() == "cpu" ? 0u : 4u);
  EXPECT_EQ(s.mismatches, 0u);
  EXPECT_EQ(s.failures, 0u);
  EXPECT_EQ(r->running().name, GetParam());
}

TEST_P(StageRunnerOn, WrongResultsAreCaughtAndReplacedByTheCpus) {
  BackendRequest req;
  req.corrupt_after = 1;  // from the second batch on, every thickness is 1 mm off
  Received got;
  const auto r = run(req, 1.0, got);
  SKIP_IF_UNAVAILABLE(r);
  expect_reference(got);
  const StageRunnerStats s = r->stats();
  EXPECT_EQ(s.verified, 4u);
  EXPECT_EQ(s.mismatches, 3u);
  EXPECT_EQ(s.failures, 0u);
}

TEST_P(StageRunnerOn, UnverifiedWrongResultsGoThroughUnnoticed) {
  // The check above is not vacuous: without verification the corruption reaches the sink.
  BackendRequest req;
  req.corrupt_after = 1;
  Received got;
  const auto r = run(req, 0.0, got);
  SKIP_IF_UNAVAILABLE(r);
  EXPECT_EQ(r->stats().verified, 0u);
  ASSERT_EQ(got.thickness.size(), want_.thickness.size());
  size_t off = 0;
  for (size_t i = 0; i < got.thickness.size(); ++i)
    off += got.valid[i] && std::fabs(got.thickness[i] - want_.thickness[i]) > 0.5;
  EXPECT_GT(off, 0u);
}

TEST_P(StageRunnerOn, AFailureMidStreamRerunsTheBatchesInFlightOnTheCpu) {
  for (int fail_after : {0, 1, 3}) {
    SCOPED_TRACE("device fails after " + std::to_string(fail_after) + " batches");
    BackendRequest req;
    req.fail_after = fail_after;
    Received got;
    const auto r = run(req, 0.01, got);
    SKIP_IF_UNAVAILABLE(r);
    expect_reference(got);
    const StageRunnerStats s = r->stats();
    EXPECT_EQ(s.batches, 4u);
    EXPECT_EQ(s.failures, 1u);
    EXPECT_EQ(r->running().name, "cpu");
    EXPECT_NE(r->note().find("injected failure"), std::string::npos) << r->note();
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, StageRunnerOn,
                         ::testing::Values("cpu", "cpu-portable", "opencl", "vulkan"),
                         [](const auto& info) {
                           std::string n = info.param;
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });

TEST(StageRunner, ABackendThatCannotStartLeavesTheServerOnTheCpuAndSaysWhy) {
  BackendRequest req;
  req.name = "vulkan";
  req.device = "no such device";
  std::vector<LaneConfig> lanes = three_lanes();
  StageRunner r(
      lanes, {req, 0.01}, [](auto&, const auto&, double) {}, [](auto&, const auto&) {});
  EXPECT_EQ(r.running().name, "cpu");
  EXPECT_NE(r.note().find("cannot start"), std::string::npos) << r.note();
}

TEST(StageRunner, LanesOfDifferentShapesRunInSeparateGroups) {
  std::vector<LaneConfig> lanes = {sized_lane(4, 640, 200), sized_lane(7, 320, 120)};
  std::vector<int64_t> order;
  size_t items = 0;
  StageRunner r(
      lanes, {cpu_request(), 0.01},
      [&](std::vector<QueuedLine>& lines, const LineResults& res, double) {
        for (const QueuedLine& q : lines) order.push_back(q.line.encoder);
        items += res.thickness.size();
      },
      [](auto&, const auto&) { ADD_FAILURE(); });
  std::vector<QueuedLine> batch(4);
  for (int k = 0; k < 4; ++k) {
    const LaneConfig& l = lanes[k % 2];
    batch[k].line.lane = l.id;
    batch[k].line.encoder = k;
    batch[k].line.cam0.assign(size_t(l.frame_width) * l.frame_height, '\0');
    batch[k].line.cam1 = batch[k].line.cam0;
  }
  r.launch(std::move(batch));
  r.finish_all();
  // Each group's lines in their order; lane 4's group first.
  EXPECT_EQ(order, (std::vector<int64_t>{0, 2, 1, 3}));
  EXPECT_EQ(items, size_t(2 * lanes[0].xray.pixels + 2 * lanes[1].xray.pixels));
}

// The CPU backend's two staging slots, each computed by its own worker: two batches in
// flight come back with the reference's results whichever is collected first, a third is
// refused, a slot collected twice is refused, and a backend dropped with a batch in flight
// waits for it.
TEST(CpuBackend, TwoBatchesInFlightComputeAsTheReferenceAndMisuseIsRefused) {
  const std::vector<LaneConfig> lanes = three_lanes();
  const SimLines a(lanes, 2, 100), b(lanes, 1, 300);
  const LinePipeline ref(lanes, 1);
  LineResults want_a, want_b;
  ref.run(a.frames.data(), a.lines, a.lane_slot.data(), want_a);
  ref.run(b.frames.data(), b.lines, b.lane_slot.data(), want_b);
  auto fill = [](LineBatchSlot& slot, const SimLines& s) {
    std::memcpy(slot.frames(), s.frames.data(), s.frames.size());
    std::copy(s.lane_slot.begin(), s.lane_slot.end(), slot.lane_slot());
  };
  auto expect_same = [](const LineResults& got, const LineResults& want, int round) {
    EXPECT_EQ(got.profile, want.profile) << "round " << round;
    EXPECT_EQ(got.profile_valid, want.profile_valid) << "round " << round;
    EXPECT_EQ(got.thickness, want.thickness) << "round " << round;
    EXPECT_EQ(got.thickness_valid, want.thickness_valid) << "round " << round;
  };
  CpuBackend cpu;
  cpu.set_lanes(lanes);
  for (int round = 0; round < 3; ++round) {  // the same workers, batch after batch
    LineBatchSlot& sa = cpu.acquire(a.lines);
    fill(sa, a);
    cpu.submit(sa);
    LineBatchSlot& sb = cpu.acquire(b.lines);
    fill(sb, b);
    cpu.submit(sb);
    try {
      cpu.acquire(1);
      ADD_FAILURE() << "a third slot was handed out";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("both staging slots are in flight"), std::string::npos)
          << e.what();
    }
    LineResults got_a, got_b;
    cpu.collect(round % 2 ? sa : sb, round % 2 ? got_a : got_b);
    cpu.collect(round % 2 ? sb : sa, round % 2 ? got_b : got_a);
    expect_same(got_a, want_a, round);
    expect_same(got_b, want_b, round);
    try {
      LineResults again;
      cpu.collect(sa, again);
      ADD_FAILURE() << "a batch was collected twice";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("not submitted"), std::string::npos) << e.what();
    }
  }
  // Dropped in flight: the slot's worker finishes into memory that is still there (a
  // worker left writing into freed slots crashes here, or hangs until ctest's timeout).
  auto dropped = std::make_unique<CpuBackend>();
  dropped->set_lanes(lanes);
  LineBatchSlot& s = dropped->acquire(a.lines);
  fill(s, a);
  dropped->submit(s);
  dropped.reset();
}

}  // namespace
