#include "bench/memory_source.h"

#include <algorithm>

#include "sim/plant_simulator.h"

namespace rangex::cli {

std::vector<v1::LineScan> render_lane_lines(const LaneConfig& lane, int fillets, int64_t max_lines,
                                            uint64_t seed) {
  sim::SimulationParams sp;
  sp.seed = seed;
  sp.scene.fillets = fillets;
  sp.scene.lead_in_mm = 10;
  const sim::LaneSimulator sim(lane, sp);
  const int64_t lines = std::min<int64_t>(max_lines, sim.lines());
  const size_t frame = size_t(lane.frame_width) * lane.frame_height;
  std::vector<v1::LineScan> scans(static_cast<size_t>(lines));
  for (int64_t k = 0; k < lines; ++k) {
    std::string c0(frame, '\0'), c1(frame, '\0'), x(size_t(lane.xray.pixels) * 2, '\0');
    sim.render(k, reinterpret_cast<uint8_t*>(c0.data()), reinterpret_cast<uint8_t*>(c1.data()),
               reinterpret_cast<uint16_t*>(x.data()), nullptr, nullptr, nullptr);
    scans[size_t(k)].set_encoder(sim.encoder(k));
    scans[size_t(k)].set_cam0(std::move(c0));
    scans[size_t(k)].set_cam1(std::move(c1));
    scans[size_t(k)].set_xray(std::move(x));
  }
  return scans;
}

}  // namespace rangex::cli
