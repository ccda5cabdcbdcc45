// Per-fillet images for people and audits: 16-bit X-ray, thickness (0.01 mm, 65535 where
// not measured), pseudo-X-ray and compensated residual (I - P + 32768), and an RGB overlay
// of the X-ray with the fillet outline, bone fragments (red) and air pockets (blue). A
// dual-energy fillet adds its bone image (um of bone-equivalent + 32768) and fat share
// (0..1 as 0..65535).
#pragma once
#include <string>

#include "pipeline/fillet_image.h"
#include "pipeline/inspection.h"

namespace rangex {

// Writes into `dir` (created). The result must have been inspected with images kept.
void write_fillet_images(const std::string& dir, const FilletImage& img, const FilletResult& r);

}  // namespace rangex
