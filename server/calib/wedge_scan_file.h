// A dual-energy step-wedge scan on disk, as `rangexctl calib simulate dual-energy` writes it
// and a plant records its wedge: wedge.yaml (the drawing: core/dual_energy_wedge.h, and the
// detector's pixels and lines), low.u16 and high.u16 (each layer's lines, little-endian,
// lines x pixels). Reading it takes each step's flat middle: its mean and variance per layer,
// and its thicknesses along the rays (the fan's slant: a slab of d mm is d / cos(theta) mm
// along a ray that leaves the vertical by theta).
#pragma once
#include <string>

#include "core/dual_energy_wedge.h"
#include "core/fan_beam.h"

namespace rangex {

std::string wedge_layout_yaml(const WedgeLayout& w, int pixels);
void write_wedge_scan(const std::string& dir, const WedgeLayout& w, int pixels,
                      const std::vector<uint16_t>& low, const std::vector<uint16_t>& high);

// Throws Error naming what is wrong: a missing or short file, a drawing outside the
// detector, a step whose middle is not flat (the wedge not where the drawing puts it).
WedgeScan read_wedge_scan(const std::string& dir, const FanBeam& beam);

}  // namespace rangex
