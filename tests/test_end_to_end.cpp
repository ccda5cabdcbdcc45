// Simulated recording -> offline replay -> accuracy against truth.
#include <gtest/gtest.h>

#include "core/plant_config.h"
#include "offline/evaluation.h"
#include "offline/replay.h"
#include "sim/plant_simulator.h"
#include "temp_dir.h"

using namespace rangex;

TEST(EndToEnd, ThicknessWithinDissertationAccuracy) {
  test::TempDir t;
  const PlantConfig plant = load_plant_config(RANGEX_SOURCE_DIR "/config/plant.yaml");
  sim::SimulationParams p;
  p.lanes = 1;
  p.scene.fillets = 2;
  p.seed = 3;
  sim::simulate_recording(plant, p, t.str("rec"));
  const RecordingReader rec(t.str("rec"));
  const auto lanes = replay_recording(rec, plant, {});
  ASSERT_EQ(lanes.size(), 1u);
  const LaneEvaluation ev =
      evaluate_lane(rec, plant.lane(0), lanes[0].stripe_rows, lanes[0].thickness);
  std::printf("%s", evaluations_table({ev}).c_str());
  ASSERT_GT(ev.thickness.count, 10000u);
  // Table 5's worst calibrated block error is 0.291 mm.
  EXPECT_LE(ev.thickness.mean_abs, 0.3);
  EXPECT_LE(ev.thickness.p99_abs, 1.0);
  EXPECT_GE(ev.fillet_coverage, 0.97);
  for (int c = 0; c < 2; ++c) {
    EXPECT_GE(ev.stripe_detected[c], 0.99) << "camera " << c;
    EXPECT_LE(ev.stripe_false[c], 0.01) << "camera " << c;
    EXPECT_LE(ev.stripe_fillet[c].mean_abs, 0.1) << "camera " << c;
  }
}

TEST(EndToEnd, SimulatorIsDeterministicForASeed) {
  const PlantConfig plant = default_plant_config(1);
  sim::SimulationParams p;
  p.scene.fillets = 1;
  p.seed = 9;
  const sim::LaneSimulator a(plant.lanes[0], p), b(plant.lanes[0], p);
  const size_t frame = 640 * 200;
  std::vector<uint8_t> a0(frame), a1(frame), b0(frame), b1(frame);
  std::vector<uint16_t> ax(480), bx(480);
  const int64_t n = a.lines() / 2;
  a.render(n, a0.data(), a1.data(), ax.data(), nullptr, nullptr, nullptr);
  b.render(n, b0.data(), b1.data(), bx.data(), nullptr, nullptr, nullptr);
  EXPECT_EQ(a0, b0);
  EXPECT_EQ(a1, b1);
  EXPECT_EQ(ax, bx);
  p.seed = 10;
  const sim::LaneSimulator c(plant.lanes[0], p);
  c.render(n, b0.data(), b1.data(), bx.data(), nullptr, nullptr, nullptr);
  EXPECT_NE(a0, b0);
}
