// The inspection's steps written the straightforward way (a fresh std::vector per pixel,
// full sorts for medians, a non-separable smoothing window), as the benchmark's baseline.
// Same arithmetic as pipeline/inspection.cpp, so the two must reach the same decision.
#pragma once
#include "pipeline/inspection.h"

namespace rangex {

FilletResult inspect_fillet_naive(const FilletImage& img, const InspectionParams& p);

}  // namespace rangex
