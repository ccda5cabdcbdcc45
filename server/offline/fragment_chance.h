// What a fragment's bone would show at the thresholds a lane uses were it a sphere, apart
// from the texture that happened to lie on it. The fragment's own bone (its volume at its
// excess attenuation over the meat, from the truth) is packed into a sphere and injected once
// more where it lies (pipeline/test_pieces.h): what the fillet's round and needle statistics
// gain there is that sphere's noise-free response, E, in the statistic's unit spread.
// Against the threshold T where it peaks, Phi(E - T) is the chance the statistic clears it
// with the texture's unit spread added. A plant's recall against the sum of its fragments'
// chances says how much of what was missed is the bone's amount and depth (a low chance)
// and how much is the way it lies: spread flat, or among fat.
//
// Why a sphere: the round kernels are whitened matched filters for spheres (C^-1 s), the
// best linear detectors of such a piece in the learned texture; a fragment of the same bone
// spread flatter puts more of its signal where the texture is strong, and shows less.
//
// What it is not: the fragment's own response. Detection is not linear where bright meat is
// clipped (a fat streak's pixels held at the clip): a second piece on a fragment that
// already darkened such pixels adds more than the first did. And the chance is the
// statistic's at the peak: a detection also needs its area (two pixels or more), which
// lowers it, while the texture crossing the threshold beside the peak raises it. On
// synthetic fillets (test_fragment_chance) pieces whose chances summed to 35.6 of 40 were
// found 28 times, and crossed the threshold within 2 mm 39 times.
#pragma once
#include <vector>

#include "offline/detection_eval.h"
#include "pipeline/inspection.h"
#include "pipeline/lane_processor.h"

namespace rangex {

// For a bone of `volume_mm3` at `excess_per_mm` over the meat, at (x_mm, b_mm) (across the
// belt at mid-depth, belt position: as detections are placed), its response looked for
// within tol_mm, in the fillet `img` inspected with `p`. Unmeasured (chance -1) off the
// fillet, without thickness there, or without a statistic.
FragmentChance fragment_chance(const FilletImage& img, const InspectionParams& p, double x_mm,
                               double b_mm, double tol_mm, double volume_mm3, double excess_per_mm);

// Each calcified fragment >= 2 mm of `e` on `lane` judged (and each miss), in the inspected
// fillet (with its pixels) that holds it: its chance filled where the truth weighs its bone.
void measure_fragment_chances(DetectionEval& e, int lane,
                              const std::vector<InspectedFillet>& fillets,
                              const InspectionParams& p);

// The recall the fragments' bone allows: the mean chance over the calcified fragments >= 2 mm
// measured (n: how many), -1 when none.
double expected_recall(const DetectionEval& e, int& n);

}  // namespace rangex
