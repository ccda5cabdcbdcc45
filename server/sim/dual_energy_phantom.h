// The dual-energy calibration phantom scanned on the belt (core/dual_energy_wedge.h): a step
// wedge of A-150 plastic (0-60 mm in 5 mm steps) crossed with one of aluminium (0-6 mm in
// 1 mm steps),
// each step's pixels rendered through the sandwich detector with its noise (a 10 mm step:
// 25 pixels x 4,000 lines of 0.4 mm, the wedge passed a few times). The wedge's
// geometry (edges, the fan's slant) is left out: a step is its flat middle, as the
// calibration reads it.
#pragma once
#include <cstdint>

#include "core/dual_energy_wedge.h"
#include "core/fan_beam.h"
#include "sim/dual_energy_renderer.h"

namespace rangex::sim {

WedgeScan simulate_wedge_scan(const DualEnergyRenderer& detector, uint64_t seed,
                              int pixels_per_step = 100000);

// The wedge laid on the belt as `w` draws it and scanned line by line through the lane's fan
// beam (each ray's path through the slabs slanted as the fan gives it): each layer's lines
// (lines x pixels), bare belt outside the wedge. The steps' edges are sharp.
void render_wedge_lines(const DualEnergyRenderer& detector, const FanBeam& beam,
                        const WedgeLayout& w, uint64_t seed, std::vector<uint16_t>& low,
                        std::vector<uint16_t>& high);

}  // namespace rangex::sim
