// Renders one camera's Mono8 frame of the laser stripe for one line (Laser Range Imaging §5.3.2): a
// Gaussian core plus a one-sided sub-surface scattering tail whose weight depends on the
// viewing angle to the surface (eq. 14), speckle, sensor noise, 8-bit saturation, and
// occlusion by the fillet's own curvature. The true stripe row per column is returned.
#pragma once
#include <cstdint>
#include <vector>

#include "core/lane_config.h"
#include "sim/lane_scene.h"
#include "sim/rng.h"
#include "sim/stripe_profile.h"

namespace rangex::sim {

struct CameraRenderParams {
  double core_sigma_px = 1.1;
  double meat_amplitude = 200;  // DN at the core's peak, before speckle
  double belt_amplitude = 140;
  double meat_tail_base = 0.12;  // tail energy / core energy on meat, head-on view
  double meat_tail_gain = 0.45;  // extra tail as the view turns away from the normal
  double belt_tail = 0.03;
  double meat_tail_px = 2.5;  // tail decay length in the image
  double belt_tail_px = 1.5;
  double speckle = 0.15;         // multiplicative, per pixel
  double column_speckle = 0.10;  // multiplicative, per column (lognormal sigma)
  double background = 6;         // DN
  double read_noise = 1.5;       // DN
  // A plant's own physics (sim/plant_physics.h); the defaults are the nominal simulator.
  int tail_direction = 1;             // -1: the scattered light leaves toward the camera
  double speckle_correlation_px = 0;  // along a column (AR(1)); 0: independent pixels
  double defocus_px_per_mm = 0;       // core sigma grows with height above the belt
  double glint_probability = 0;       // a meat column glints: 4-10x brighter, narrower
  double belt_texture = 0;            // the belt's reflectance varies by this much
};

class CameraRenderer {
 public:
  CameraRenderer(const LaneConfig& lane, int camera, CameraRenderParams p = {});

  // belt_offset_mm = line * encoder step. truth_row: width entries, NaN where no stripe.
  // Scene: LaneScene (fillets) or CalibScene (calibration objects).
  template <typename Scene>
  void render(const Scene& scene, double belt_offset_mm, Rng& rng, uint8_t* frame,
              float* truth_row) const;

 private:
  const CameraModel& cam_;
  double laser_y_;
  int width_, height_;
  CameraRenderParams p_;
  int tail_sign_;               // +1: the tail runs toward larger rows in this camera's image
  std::vector<uint8_t> noise_;  // background + read noise, drawn from in blocks
  StripeKernel meat_kernel_, belt_kernel_;
};

}  // namespace rangex::sim
