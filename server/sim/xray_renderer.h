// Renders one X-ray detector line (seed ch. 7.3.2): for each pixel the fan-beam ray from the
// source, Beer-Lambert attenuation through meat with texture, fat, air pockets and bone
// fragments (eq. 52-57), Poisson photon noise plus electronic noise, 12-bit output. Returns
// the true X-ray path length through the meat per pixel.
#pragma once
#include <cstdint>

#include "core/lane_config.h"
#include "sim/lane_scene.h"
#include "sim/rng.h"

namespace rangex::sim {

struct XrayRenderParams {
  double open_beam_dn = 3600;   // I0 on the bare belt
  double photons_per_dn = 10;   // sets the Poisson noise
  double electronic_noise = 2;  // DN
};

class XrayRenderer {
 public:
  XrayRenderer(const LaneConfig& lane, XrayRenderParams p = {});
  // belt_offset_mm = line * encoder step; thickness: per pixel path length in mm.
  void render(const LaneScene& scene, double belt_offset_mm, Rng& rng, uint16_t* line,
              float* thickness) const;

 private:
  FanBeam fb_;
  double xray_y_;
  XrayRenderParams p_;
};

}  // namespace rangex::sim
