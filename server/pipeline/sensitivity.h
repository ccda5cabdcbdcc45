// The sensitivity that a lane's thresholds buy: test pieces (test_pieces.h) of several sizes,
// both shapes, at several depths, injected into clean fillets, each fillet inspected with
// the lane's inspection settings; per shape, size and thickness band, how many were found.
// From it the claim a plant can check: per band the smallest size found at >= 95 % with
// confidence (the detection curve's lower bound, detection_curve.h).
#pragma once
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "pipeline/fillet_image.h"
#include "pipeline/test_pieces.h"

namespace rangex {

struct SensitivityOptions {
  std::vector<double> sizes_mm = {1, 1.5, 2, 2.5, 3, 4, 5};
  std::vector<double> depths = {0.25, 0.5, 0.75};  // centre height as a fraction of the meat
  int pieces_per_fillet = 4;                       // per fillet, shape and size
  double spacing_mm = 12;                          // between pieces in one fillet
  double edge_margin_mm = 3;                       // from the meat's edge
  TestPieceMaterial material;
  uint64_t seed = 7;
  std::vector<double> band_edges_mm;  // empty: the learned bands, else the default ones
  double rate = 0.95;                 // the detection rate a claim stands for
  int min_pieces = 10;                // per cell, to claim anything
  // A claim stands where the detection curve's lower bound at this one-sided confidence
  // reaches `rate` (detection_curve.h), as well as the rate seen at that size.
  double claim_confidence = 0.95;
  // learn_lane: measured for a learning that failed too. Its report then says what the
  // thresholds would buy (a forced activation needs it); a command that writes nothing for a
  // failed learning refuses sooner without (the test pieces are most of a learning's time).
  bool when_learning_failed = true;
};

struct SensitivityCell {
  int shape = 0;  // TestPiece::Shape
  double size_mm = 0;
  int band = 0;
  int injected = 0, found = 0;
};

// Per shape and band: the smallest size at which, and at every larger size, the pieces were
// found at >= rate and the band's detection curve's lower bound is >= rate.
struct SensitivityClaim {
  int shape = 0, band = 0;
  double band_lo_mm = 0, band_hi_mm = 0;
  double size_mm = 0;
  double pod_lower = NAN;  // the curve's lower bound at size_mm
};

// What the report states, per shape (its summary sentence, `text`): `size_mm` found at
// >= rate in every band from `first_band` (the thinnest seen, unless that claims nothing) to
// `last_band`, i.e. up to `up_to_mm` of meat.
struct StatedClaim {
  int shape = 0;
  double size_mm = 0;
  int first_band = 0, last_band = 0;
  double up_to_mm = 0;
  std::string text;
};

struct SensitivityResult {
  std::vector<double> band_edges_mm;
  std::vector<SensitivityCell> cells;
  std::vector<SensitivityClaim> claims;
  std::vector<std::string> summary;  // "2.0 mm sphere at 95 % up to 20 mm of meat"
  std::vector<StatedClaim> stated;   // what the summary says, one per sentence
  int inspections = 0;
  double rate = 0, claim_confidence = 0;  // the options the claims were made with
  TestPieceMaterial material;             // the pieces' bone, as injected
};

struct SensitivityFillet {
  const FilletImage* image = nullptr;  // a clean fillet with its pixels
  // Its meat's attenuation per mm at thickness t: -(beta1 + 2 beta2 t), the fit's slope.
  double beta1 = -0.03, beta2 = 0;
  double meat_mu(double t) const;
};

// The report's sentences (`summary`, `stated`) from `cells` and `claims`, per shape: the
// smallest size claimed in every band from the thinnest seen up to some thickness; where the
// thinnest bands claim nothing (a steep wall's rim, say), the same from the first band that
// claims a size ("2.0 mm calcified sphere at 95 % from 10 mm of meat up to 30 mm").
void state_claims(SensitivityResult& res, const SensitivityOptions& opt);

// The claims that `cells` support, per shape and band (see SensitivityClaim).
std::vector<SensitivityClaim> claim_sizes(const std::vector<SensitivityCell>& cells,
                                          const std::vector<double>& band_edges_mm,
                                          const SensitivityOptions& opt);

SensitivityResult measure_sensitivity(const std::vector<SensitivityFillet>& fillets,
                                      const InspectionParams& p, const SensitivityOptions& opt,
                                      const std::function<void(int, int)>& progress = {});
// The same pieces, placed once, found under each of several learned thresholds (p.learned
// replaced by each; result k is measure_sensitivity's with learned[k]): a fillet's model and
// statistics are made once for all of them where they share them (inspect_fillet_each).
std::vector<SensitivityResult> measure_sensitivity_each(
    const std::vector<SensitivityFillet>& fillets, const InspectionParams& p,
    const std::vector<LearnedDetection>& learned, const SensitivityOptions& opt,
    const std::function<void(int, int)>& progress = {});

// A claim checked on other fillets: the pieces of its shape and size found there; held when
// at least the claimed rate of them were. A few dozen pieces fall one or two short of the
// rate by chance about as often as not, so the check also says how likely so few found are
// if the claim is true (`p_at_rate`, the binomial lower tail at the claimed rate), and
// `contradicted` when that is under `kClaimContradiction`: evidence against the claim.
template <class Claim>
struct Checked {
  Claim claim;
  int injected = 0, found = 0;
  bool held = false;
  double rate = 0;  // claimed
  double p_at_rate = 1;
  bool contradicted = false;
};
constexpr double kClaimContradiction = 0.05;
using ClaimCheck = Checked<SensitivityClaim>;
using StatedCheck = Checked<StatedClaim>;

// "needle 3.0 mm at 10-15 mm of meat: 14 of 15 found (93.3 %): not held; at a true 95 %
// this few or fewer in 54 % of checks: no evidence against it" (the sentence's check
// without its shape and band).
std::string claim_check_text(const ClaimCheck& k);
std::string claim_check_text(const StatedCheck& k);

// Each of `claims` checked on `measured` (e.g. fillets not used for learning), at its size
// and band.
std::vector<ClaimCheck> check_claims(const std::vector<SensitivityClaim>& claims,
                                     const SensitivityResult& measured, double rate);
// Each stated claim checked on `measured`: the pieces of its shape and size in the bands it
// covers, pooled (what a plant reading the sentence expects).
std::vector<StatedCheck> check_stated_claims(const std::vector<StatedClaim>& stated,
                                             const SensitivityResult& measured, double rate);

const char* piece_shape_name(int shape);

}  // namespace rangex
