// What the backend suites share: which backends this run requires, lanes with different
// settings and calibrations, and simulated lines of several lanes interleaved.
#pragma once
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "sim/plant_simulator.h"

namespace rangex::test {

// A backend named in RANGEX_REQUIRE_BACKENDS must start: the suites fail, not skip, without it.
inline bool required(const std::string& name) {
  const char* r = std::getenv("RANGEX_REQUIRE_BACKENDS");
  if (!r) return false;
  std::stringstream ss(r);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item == name) return true;
  }
  return false;
}

// A lane's configuration at another frame size (the camera models follow it).
inline LaneConfig sized_lane(int id, int width, int height) {
  LaneConfig l = default_lane_config(id);
  l.frame_width = width;
  l.frame_height = height;
  for (auto& cam : l.cameras)
    cam.model = CameraModel(cam.model.intrinsics(), cam.model.distortion(), cam.model.rotation(),
                            cam.model.translation(), width, height);
  return l;
}

// Three lanes with different settings and calibrations: stripe methods and constants, laser
// plane, fusion tolerances, fan-beam geometry.
inline std::vector<LaneConfig> three_lanes(int width = 640, int height = 200) {
  std::vector<LaneConfig> v;
  for (int i = 0; i < 3; ++i) v.push_back(sized_lane(i, width, height));
  v[1].stripe.method = StripeMethod::kGaussian3;
  v[1].stripe.threshold_rel = 0.3;
  v[1].cameras[0].scatter = {0.1, -0.2, 0.05};
  v[1].laser.offset_mm = 0.4;
  v[1].fusion.agree_tol_mm = 0.5;
  v[1].xray.source_x_mm = 6.0;
  v[2].stripe.method = StripeMethod::kBinary;
  v[2].stripe.min_peak = 60;
  v[2].stripe.max_width = 20;
  v[2].laser.offset_mm = -0.3;
  v[2].fusion.max_gap_mm = 1.0;
  v[2].xray.source_z_mm = 650.0;
  return v;
}

// Lines of three simulated lanes (each with its own configuration), interleaved, fillets
// passing under the laser: frames [line][camera] and each line's lane slot.
struct SimLines {
  std::vector<uint8_t> frames;
  std::vector<int> lane_slot;
  int lines = 0;
  SimLines(const std::vector<LaneConfig>& lanes, int per_lane, int64_t first) {
    sim::SimulationParams sp;
    sp.scene.fillets = 1;
    sp.seed = 11;
    std::vector<sim::LaneSimulator> sims;
    for (const auto& l : lanes) sims.emplace_back(l, sp);
    const size_t frame = size_t(lanes[0].frame_width) * lanes[0].frame_height;
    std::vector<uint16_t> xray(lanes[0].xray.pixels);
    for (int n = 0; n < per_lane; ++n)
      for (size_t s = 0; s < lanes.size(); ++s) {
        frames.resize(frames.size() + 2 * frame);
        uint8_t* f = frames.data() + frames.size() - 2 * frame;
        sims[s].render(first + n, f, f + frame, xray.data(), nullptr, nullptr, nullptr);
        lane_slot.push_back(int(s));
        ++lines;
      }
  }
  std::vector<int> frame_slot() const {
    std::vector<int> fs;
    for (int s : lane_slot) {
      fs.push_back(2 * s);
      fs.push_back(2 * s + 1);
    }
    return fs;
  }
};

}  // namespace rangex::test
