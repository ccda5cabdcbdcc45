// A fillet image with known answers, for tests and benchmarks of the inspection: a dome of
// thickness whose X-ray follows ln I = b0 + b1 T exactly, photon and electronic noise, and
// planted bones (or air pockets) at known positions.
#pragma once
#include <cstdint>
#include <vector>

#include "pipeline/fillet_image.h"

namespace rangex::sim {

struct PlantedBone {
  double x_mm, y_mm, radius_mm;
  double attenuation;  // -ln(I / P) at the centre; negative for an air pocket
};

// rows x cols pixels of 0.4 mm, parallel beam (detector x is belt x), x0 = -40 mm,
// y0 = 100 mm; 10 photons per DN and 2 DN electronic noise. hardening h > 0 bends the meat's
// attenuation a = -b1 T to a / (1 + h a), a polychromatic beam's (0: the straight line).
FilletImage synthetic_fillet(double b0, double b1, const std::vector<PlantedBone>& bones,
                             uint64_t seed, int rows = 300, int cols = 200, double hardening = 0);

}  // namespace rangex::sim
