// Renders one X-ray detector line (Laser Range Imaging ch. 7.3.2): for each pixel the fan-beam ray
// from the source, Beer-Lambert attenuation through meat with texture, fat, air pockets and bone
// fragments (eq. 52-57), Poisson photon noise plus electronic noise, 12-bit output. Returns
// the true X-ray path length through the meat per pixel.
//
// A plant's X-ray physics (sim/plant_physics.h) adds what real detectors do: the pixel's
// aperture and line-spread function, the focal spot's blur (growing with the object's
// height), an X-ray plane a fraction of a line off and turned against the laser's, and beam
// hardening. With none of them the nominal renderer runs unchanged.
//
// A lane of two energies (xray.energies: 2) is rendered through its sandwich detector
// (sim/dual_energy_renderer.h): each ray's materials (the meat as lean and fat, bone as
// cortical bone and cartilage by its calcification, cartilage and tendon as soft tissue, air
// as nothing) through NIST's coefficients, so that the beam hardens as its spectrum does
// (`hardening` is not applied) and each layer has its own noise.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "core/lane_config.h"
#include "sim/dual_energy_renderer.h"
#include "sim/lane_scene.h"
#include "sim/plant_physics.h"
#include "sim/rng.h"

namespace rangex::sim {

struct XrayRenderParams {
  double open_beam_dn = 3600;   // I0 on the bare belt
  double photons_per_dn = 10;   // sets the Poisson noise
  double electronic_noise = 2;  // DN
};

class XrayRenderer {
 public:
  XrayRenderer(const LaneConfig& lane, XrayRenderParams p = {}, XrayPhysics physics = {});
  // belt_offset_mm = line * encoder step; thickness: per pixel path length in mm; high: the
  // high-energy line of a lane of two energies (`line` is then the low one).
  void render(const LaneScene& scene, double belt_offset_mm, Rng& rng, uint16_t* line,
              float* thickness, uint16_t* high = nullptr) const;
  bool dual_energy() const { return de_ != nullptr; }
  // The laser-to-X-ray offset along the belt where the X-ray sees (x, z), mm.
  double plane_y(double x, double z) const;

 private:
  // Attenuation (ln I0/I) along the ray from detector position (xd, zd) to the source
  // point xs, through the slice at belt position b; path: the meat's path length.
  double attenuation(const LaneScene& scene, double b, double xd, double zd, double xs,
                     double* path) const;
  FanBeam fb_;
  double xray_y_, step_;
  XrayRenderParams p_;
  XrayPhysics ph_;
  std::vector<float> gain_;       // the flat-field residual per pixel (empty: none)
  std::vector<float> gain_high_;  // the high layer's (dual energy)
  std::shared_ptr<const DualEnergyRenderer> de_;
};

}  // namespace rangex::sim
