// Each line stage's cases, declared once with their tolerances, in the manner of ggml's
// test-backend-ops: a case names its stage, runs it on a backend over one batch of inputs,
// and says where a result differs from the reference's beyond what the case allows. The
// backend suite runs every case on every backend against the CPU backend (the reference);
// `rangexctl bench --backend` times the same cases.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "backends/backend.h"
#include "offline/dual_energy_work.h"
#include "pipeline/pseudo_xray.h"

namespace rangex {

// `count` distinct lines of a simulated lane with fillets in it, spread over its scene: both
// cameras' frames of each, [line][camera][row][column].
std::vector<uint8_t> render_distinct_lines(const LaneConfig& lane, int count);

// A batch of `lines` lines over `lanes` lanes (line k on lane k % lanes) repeating the lines
// of `rendered`, and each line's lane slot and each frame's slot.
struct LineBatchInputs {
  int lanes = 0, lines = 0;
  size_t frame = 0;             // bytes of one camera's frame
  std::vector<uint8_t> frames;  // [line][camera][row][column]
  std::vector<int> lane_slot, frame_slot;
};
LineBatchInputs interleave_lines(const std::vector<uint8_t>& rendered, size_t frame, int lanes,
                                 int lines);

// One batch's inputs for every stage, made once and shared by every backend: `lines` lines of
// `lanes` lanes (line k on lane k % lanes, each lane with its own settings) from a simulated
// lane with fillets in it; the CPU pipeline's results of them (the later stages' inputs);
// and a batch of fillets for the pseudo-X-ray stages.
struct StageWork {
  std::vector<LaneConfig> lanes;
  LineBatchInputs batch;
  LineResults ref;
  std::vector<float> fillet_thickness;
  std::vector<uint16_t> fillet_xray;
  std::vector<uint8_t> fillet_use;
  std::vector<int32_t> fillet_offsets;
  std::vector<FilletModel> fillet_models;
  FilletBatch fillets() const;
  // A batch of pixels for the dual-energy stages (offline/dual_energy_work.h) with the
  // calibration they were drawn for; the CPU reference's basis of them and a fat share for
  // the bone stage.
  DualEnergyParams de_params{};
  DualEnergyRays de_rays;
  std::vector<float> de_basis, de_phi, de_phi_var;
  DualEnergyBoneBatch de_bone() const;
};
// `lane`: the lane every lane of the work starts from (its frame size and geometry).
StageWork make_stage_work(const LaneConfig& lane, int lanes, int lines, int fillets = 4,
                          int fillet_pixels = 20000, int dual_energy_pixels = 20000);

// What a stage writes (only its own fields are filled).
struct StageOutput {
  StripeOutput stripes;
  std::vector<float> x, z, profile, thickness;
  std::vector<uint8_t> xz_valid, profile_valid, thickness_valid;
  std::vector<float> ln_p, p, residual, score;
  std::vector<double> r, sums;
  std::vector<float> basis, lengths, length_sigma, bone, bone_sigma;
};

struct StageCase {
  std::string stage;  // stripe, rectify, fuse, project, pseudo-xray, irls, dual-energy(-bone)
  std::string what;   // what its tolerance allows, for a reader of a failure
  double items = 0;   // per run: columns, lines or pixels
  std::string unit;
  std::function<void(Backend&, const StageWork&, StageOutput&)> run;
  // The first item where `got` differs from `want` beyond the case's tolerance; "" if none.
  std::function<std::string(const StageOutput& got, const StageOutput& want)> compare;
};

// Every case over `w` (the backend must have `w.lanes` set for the line stages).
std::vector<StageCase> stage_cases(const StageWork& w);

}  // namespace rangex
