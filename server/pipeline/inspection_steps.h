// The inspection's steps that every way of modelling a fillet shares (pipeline/inspection.h:
// one energy with the laser's thickness, the X-ray-only baseline, dual energy): the
// result's header, the fail-safe checks, and the detection from a z image on.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "pipeline/inspection.h"

namespace rangex {

// The result's header and the fail-safe checks that need no model: false (with the
// result's reason) when the fillet cannot be inspected. searchable (when asked): it cannot,
// but what it has is whole and true (too much of it without thickness, or off the lane's
// edge), so it can still be searched for bone there.
bool start_inspection(const FilletImage& img, const InspectionParams& p, FilletResult& res,
                      bool* searchable = nullptr);

// start_inspection, then inspect(params, res) (which leaves res.reason on a failure) where the
// fillet can be inspected, and where it cannot but is searchable too: then it stays not
// inspected with the fail-safe's reason, the bone fragments found named after it, and no band
// extremes (learning and drift see passed fillets only).
FilletResult inspect_searchable(
    const FilletImage& img, const InspectionParams& p,
    const std::function<void(const InspectionParams&, FilletResult&)>& inspect);

// From z (per pixel: the residual over its sigma, negative where the pixel holds more than
// the model: bone) on the usable pixels: the statistics brought to unit spread, the
// thresholds (learned or fixed), fragments and air pockets, the band extremes and the
// decision. resid: what z was made of, summed over a blob as its attenuation (ln I, or mm of
// bone in dual energy); moved into the result when images are kept. fit: the single-energy
// model of ln I (a blob's contrast in mm of meat), else null. closure_z: the closed gaps'
// spread in z's units per pixel (closure_spread.h), or empty.
void detect_from_z(const FilletImage& img, const std::vector<uint8_t>& use,
                   const std::vector<float>& z, const std::vector<float>& closure_z,
                   std::vector<float>& resid, const RobustFit* fit, const InspectionParams& p,
                   bool keep, FilletResult& res);

// detect_from_z in its two steps. The statistics at unit spread come first: they depend on
// the lane's kernels, spread and smoothing, not on its thresholds, so that one fillet's can
// be decided under several sets of thresholds (inspect_fillet_each).
struct DetectionStatistics {
  std::vector<float> stat[kStatistics];    // larger: more bone-like (round, needle), air-like
  std::vector<float> zc;                   // z as the whitened kernels saw it (bright clipped)
  std::vector<int16_t> round_k, needle_k;  // the kernel each pixel's statistic is (-1: none)
};
void statistics_from_z(const FilletImage& img, const std::vector<uint8_t>& use,
                       const std::vector<float>& z, const std::vector<float>& closure_z,
                       const InspectionParams& p, FilletResult& res, DetectionStatistics& ds);
// Then the thresholds, fragments and air pockets, band extremes and the decision; with keep,
// the statistics move into the result.
void decide_from_statistics(const FilletImage& img, const std::vector<uint8_t>& use,
                            const std::vector<float>& z, std::vector<float>& resid,
                            const RobustFit* fit, DetectionStatistics& ds,
                            const InspectionParams& p, bool keep, FilletResult& res);

// One energy's model of a fillet: the fit of ln I against the thickness (as the detector
// sees it, where the lane's detector is measured), the noise model, and z on the usable
// pixels.
struct OneEnergyModel {
  bool matched = false;  // the thickness was matched to the detector: matched_image
  FilletImage matched_image;
  std::vector<uint8_t> use;
  std::vector<float> z, resid, pred;  // resid: ln I - ln P; pred: P (DN)
  std::vector<float> closure_z;       // the closures' spread in z's units; empty: none
  // The image the model was made on.
  const FilletImage& image(const FilletImage& raw) const { return matched ? matched_image : raw; }
};
// Into res: the fit and the noise model; false (with res.reason) when the fit fails.
bool one_energy_model(const FilletImage& raw, const InspectionParams& p, FilletResult& res,
                      OneEnergyModel& m);

// Whether inspect_fillet takes img in dual energy (both lines there, and the lane not set to
// its low line alone).
bool inspected_in_dual_energy(const FilletImage& img, const InspectionParams& p);

// Dual energy (pipeline/dual_energy_inspection.cpp).
FilletResult inspect_fillet_dual_energy(const FilletImage& img, const InspectionParams& p,
                                        bool keep);
// Each layer's log attenuation per mm of lean and of cortical bone at pixel i of a
// dual-energy fillet (the calibration's slopes where the pixel's reading lies): what a test
// piece adds to each line; false where the pixel cannot be taken back.
bool dual_energy_slopes(const FilletImage& img, size_t i, double lean[2], double bone[2]);

}  // namespace rangex
