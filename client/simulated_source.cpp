#include "line_source.h"
#include "sim/plant_simulator.h"

namespace rangex {

SimulatedSource::SimulatedSource(const PlantConfig& plant, const sim::SimulationParams& p)
    : plant_(plant) {
  for (int i = 0; i < p.lanes; ++i) sims_.emplace_back(plant.lanes.at(i), p);
  for (auto& s : sims_) lines_ = std::max(lines_, s.lines());
}

SimulatedSource::~SimulatedSource() = default;

std::vector<int> SimulatedSource::lanes() const {
  std::vector<int> v;
  for (size_t i = 0; i < sims_.size(); ++i) v.push_back(plant_.lanes[i].id);
  return v;
}

void SimulatedSource::line(int li, int64_t n, v1::LineScan& out) {
  const LaneConfig& lc = plant_.lanes[li];
  const size_t frame = size_t(lc.frame_width) * lc.frame_height;
  std::string c0(frame, '\0'), c1(frame, '\0'), x(size_t(lc.xray.pixels) * 2, '\0');
  // A lane of two energies sends its high line too (LineScan.xray_high).
  std::string high(lc.xray.energies == 2 ? x.size() : 0, '\0');
  sims_[li].render(n, reinterpret_cast<uint8_t*>(c0.data()), reinterpret_cast<uint8_t*>(c1.data()),
                   reinterpret_cast<uint16_t*>(x.data()), nullptr, nullptr, nullptr,
                   high.empty() ? nullptr : reinterpret_cast<uint16_t*>(high.data()));
  out.set_lane(lc.id);
  out.set_encoder(sims_[li].encoder(n));
  out.set_cam0(std::move(c0));
  out.set_cam1(std::move(c1));
  out.set_xray(std::move(x));
  if (!high.empty()) out.set_xray_high(std::move(high));
}

}  // namespace rangex
