// Plant variants: each physics part named in YAML, refused by key when wrong, the
// nominal part rendering exactly the project's simulator, and each effect present where it
// is asked for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <vector>

#include "core/error.h"
#include "core/lane_config.h"
#include "sim/plant_physics.h"
#include "sim/plant_simulator.h"

namespace rangex {
namespace {

namespace fs = std::filesystem;

std::string error_of(const std::string& yaml) {
  try {
    sim::parse_plant_physics(yaml, "v.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(PlantPhysics, ShippedVariantsLoadAndSomeAreHeldOut) {
  int held_out = 0, n = 0;
  for (const auto& e : fs::directory_iterator(RANGEX_SOURCE_DIR "/config/variants")) {
    const sim::PlantPhysics p = sim::load_plant_physics(e.path().string());
    EXPECT_EQ(p.name, e.path().stem().string());
    held_out += p.held_out;
    ++n;
    // What is written reads back the same.
    EXPECT_EQ(sim::to_yaml(sim::parse_plant_physics(sim::to_yaml(p), "again")), sim::to_yaml(p));
  }
  EXPECT_GE(n, 9);
  EXPECT_GE(held_out, 2);
}

TEST(PlantPhysics, BadInputNamesTheKey) {
  EXPECT_NE(error_of("xray: {detector_sigma: 1}").find("xray: unknown key 'detector_sigma'"),
            std::string::npos);
  EXPECT_NE(error_of("optics: {}").find("unknown section 'optics'"), std::string::npos);
  EXPECT_NE(error_of("xray: {alpha_deg: 9}").find("xray.alpha_deg: must be within -2..2"),
            std::string::npos);
  EXPECT_NE(error_of("scatter: {direction: 0}").find("scatter.direction: must be 1 or -1"),
            std::string::npos);
  EXPECT_NE(error_of("bones: {needle: 0.6, chip: 0.6}").find("add up to more than 1"),
            std::string::npos);
  EXPECT_NE(error_of("laser: {core_sigma_px: .nan}").find("laser.core_sigma_px"),
            std::string::npos);
  EXPECT_NE(error_of("bones: {needle: many}").find("bones.needle: expected a number"),
            std::string::npos);
}

struct Lines {
  std::vector<uint8_t> cam0, cam1;
  std::vector<uint16_t> xray;
};

Lines render(const sim::SimulationParams& p, int64_t first, int count) {
  const LaneConfig lane = default_lane_config(0);
  const sim::LaneSimulator s(lane, p);
  Lines l;
  const size_t frame = size_t(lane.frame_width) * lane.frame_height;
  l.cam0.resize(frame * count), l.cam1.resize(frame * count);
  l.xray.resize(size_t(lane.xray.pixels) * count);
  for (int k = 0; k < count; ++k)
    s.render(first + k, &l.cam0[frame * k], &l.cam1[frame * k], &l.xray[lane.xray.pixels * k],
             nullptr, nullptr, nullptr);
  return l;
}

sim::SimulationParams params(const std::string& yaml) {
  sim::SimulationParams p;
  p.scene.fillets = 3;
  p.seed = 5;
  p.physics = sim::parse_plant_physics(yaml, "t");
  return p;
}

TEST(PlantPhysics, NominalRendersTheProjectsSimulator) {
  sim::SimulationParams plain;
  plain.scene.fillets = 3;
  plain.seed = 5;
  const Lines a = render(plain, 400, 4), b = render(params("name: nominal"), 400, 4);
  EXPECT_EQ(a.cam0, b.cam0);
  EXPECT_EQ(a.cam1, b.cam1);
  EXPECT_EQ(a.xray, b.xray);
}

TEST(PlantPhysics, EachEffectIsRendered) {
  const LaneConfig lane = default_lane_config(0);
  // Fragment shapes and cartilage appear in the truth.
  const sim::LaneSimulator bones(
      lane, params("bones: {probability: 1, needle: 0.5, rib: 0.25, cluster: 0.25, "
                   "cartilage_probability: 1}"));
  const std::string csv = bones.fragments_csv();
  EXPECT_NE(csv.find(",needle,"), std::string::npos) << csv;
  EXPECT_NE(csv.find("cartilage,"), std::string::npos) << csv;
  // Each bone's volume is positive and within the sphere of its size (its longest extent).
  std::istringstream rows(csv);
  std::string row;
  std::getline(rows, row);
  int bones_seen = 0;
  while (std::getline(rows, row)) {
    std::vector<std::string> c;
    std::istringstream cells(row);
    for (std::string cell; std::getline(cells, cell, ',');) c.push_back(cell);
    ASSERT_EQ(c.size(), 12u) << row;
    if (c[1] != "bone") continue;
    ++bones_seen;
    const double size = std::stod(c[6]), volume = std::stod(c[9]);
    EXPECT_GT(volume, 0) << row;
    EXPECT_LE(volume, M_PI / 6 * size * size * size) << row;
    // Its attenuation over the meat is its calcification's share of bone's (0.12 /mm) over
    // the meat's own.
    const double calcification = std::stod(c[7]), excess = std::stod(c[10]),
                 meat = std::stod(c[11]);
    EXPECT_GT(meat, 0.01) << row;
    EXPECT_LT(meat, 0.06) << row;
    EXPECT_NEAR(excess, calcification * (0.12 - meat), 1e-4) << row;
  }
  EXPECT_GT(bones_seen, 0);
  // Dropped lines arrive black, at about their rate.
  const sim::LaneSimulator drop(lane, params("belt: {dropped_line_rate: 0.05}"));
  int dropped = 0;
  for (int64_t n = 0; n < 2000; ++n) dropped += drop.dropped(n);
  EXPECT_NEAR(dropped, 100, 35);
  // Glints off wet meat saturate the sensor far more often.
  auto saturated = [&](const std::string& yaml) {
    const Lines l = render(params(yaml), 300, 8);
    return std::count(l.cam0.begin(), l.cam0.end(), uint8_t(255));
  };
  const auto dry = saturated("name: nominal"), wet = saturated("speckle: {glint_probability: 0.1}");
  std::printf("saturated camera pixels over 8 lines: %ld dry, %ld with glints\n", long(dry),
              long(wet));
  EXPECT_GT(wet, 3 * dry + 20);
  // Encoder jitter moves where the line is taken: the frames differ from the nominal ones.
  EXPECT_NE(render(params("belt: {encoder_jitter_mm: 0.2}"), 300, 2).cam0,
            render(params("name: nominal"), 300, 2).cam0);
  // The detector's blur softens a steep wall in the X-ray: the largest step between
  // neighbouring pixels of a line falls.
  auto sharpest = [&](const std::string& yaml) {
    const Lines l = render(params(yaml), 300, 8);  // through the first fillet
    double sum = 0;
    for (int k = 0; k < 8; ++k) {
      double top = 0;
      for (int i = 1; i < lane.xray.pixels; ++i)
        top = std::max(top, std::abs(double(l.xray[k * lane.xray.pixels + i]) -
                                     l.xray[k * lane.xray.pixels + i - 1]));
      sum += top;
    }
    return sum / 8;
  };
  const double sharp = sharpest("shapes: {steep_fraction: 1}");
  const double blurred = sharpest("shapes: {steep_fraction: 1}\nxray: {detector_sigma_px: 1.5}");
  std::printf("steepest step across a wall: %.0f DN sharp, %.0f DN blurred\n", sharp, blurred);
  EXPECT_LT(blurred, 0.5 * sharp);
}

}  // namespace
}  // namespace rangex
