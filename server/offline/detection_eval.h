// Detection figures against the simulator's truth: fragment recall by size and
// calcification, false rejects of clean fillets, position error, residual statistics; for
// rangex and for the X-ray-only baseline on the same fillets.
#pragma once
#include <string>
#include <vector>

#include "offline/evaluation.h"
#include "offline/fillet_records.h"

namespace rangex {

struct TruthFragment {
  int lane = 0, fillet = 0;
  std::string kind;  // bone | air | cartilage
  double x_mm = 0, b_mm = 0, size_mm = 0, calcification = 0;
  std::string shape = "compact";  // compact | needle | chip | rib | cluster
  double xray_line = 0;
  // Its parts' volume (-1: a truth written before it was): a fragment's size is its longest
  // extent, and a flat one holds the bone of a much smaller sphere.
  double volume_mm3 = -1;
  // Its attenuation over the meat's and the meat's own, 1/mm (-1: a truth written before).
  double excess_mu = -1, meat_mu = -1;
};

// What a fragment's bone would show were it a sphere (offline/fragment_chance.h).
struct FragmentChance {
  int stat = -1;          // kStatRound or kStatNeedle: the one with the better chance
  double response = -1;   // E: the sphere's noise-free gain in that statistic
  double threshold = -1;  // T where the response peaks
  double chance = -1;     // Phi(E - T); -1 where it could not be measured
  // That statistic's peak within the window as the fillet is: the fragment's own response
  // with the texture on it (the same fragment in two plants: what the second's meat costs).
  double observed = -1;
};

// Each bone fragment judged, of any size and shape: what the learned report's sensitivity
// claims are held against (offline/claim_coverage.h).
struct JudgedFragment {
  int lane = 0, fillet = 0;
  std::string shape;
  double size_mm = 0, calcification = 0, volume_mm3 = -1, excess_mu = -1, meat_mu = -1;
  double meat_mm = -1;  // the true meat over it (with an EdgeMap)
  bool found = false;
  double x_mm = 0, b_mm = 0, tol_mm = 2;  // where it lies, and the matching's tolerance
  FragmentChance chance{};                // calcified >= 2 mm, where measured
};

// The lane's true X-ray path thickness (truth/thickness.f32) with the geometry to find a
// belt position in it: how far a point lies from the meat's edge (mm, up to 5 mm).
struct EdgeMap {
  const float* thickness = nullptr;  // lines x pixels
  int64_t lines = 0;
  int pixels = 0;
  double first_pixel_x_mm = 0, pitch_mm = 0.4, step_mm = 0.4;
  double source_x_mm = 0, source_z_mm = 700, detector_z_mm = -15;
  int delay_lines = 0;
  // x: across the belt at mid-depth (about 10 mm up); line: the X-ray line.
  double distance_mm(double x_mm, double xray_line) const;
  double thickness_mm(double x_mm, double xray_line) const;  // the path there (0 outside)
};

// A calcified fragment >= 2 mm that no detection matched, with what explains a miss: its
// size and calcification, and (with an EdgeMap) the true meat over it and its distance from
// the meat's edge (-1: unknown).
struct MissedFragment {
  int lane = 0, fillet = 0;
  std::string shape;
  double size_mm = 0, calcification = 0, meat_mm = -1, edge_mm = -1;
  double volume_mm3 = -1;
  double x_mm = 0, b_mm = 0, tol_mm = 2;  // where it lies, and the matching's tolerance
  // What finding it would cost (offline/miss_margin.h), when measured: the largest fraction
  // of the rejecting thresholds at which inspection finds it (0: not down to the floor; -1:
  // not measured) and the false-reject rate the learned models imply there (-1: unknown).
  double found_at = -1, frr_at = -1;
  int margin_stat = -1;     // the statistic whose thresholds were lowered (-1: every rejecting one)
  double margin_floor = 0;  // the lowest fraction tried
  FragmentChance chance{};  // its bone's, as its judged fragment's (offline/fragment_chance.h)
  // What became of the fillet that holds it: "pass" (the bone went down the line),
  // "reject" (rejected for something else found in it), "not_inspected" (rejected by the
  // fail-safe), "" (no fillet of the records holds it: not passed either).
  std::string fillet_decision{};
};

struct TruthFillet {
  int lane = 0, fillet = 0;
  double b_start = 0, b_end = 0;
  int bones = 0;
};

// Parse the simulator's truth/fragments.csv and truth/fillets.csv of one lane.
std::vector<TruthFragment> parse_truth_fragments(const std::string& text, int lane);
std::vector<TruthFillet> parse_truth_fillets(const std::string& text, int lane);

constexpr int kSizeBins = 4;  // 1-2, 2-3, 3-5, 5-10 mm
constexpr int kCalcBins = 2;  // weakly calcified (< 0.6), calcified (>= 0.6)
constexpr double kCalcified = 0.6;

struct DetectionEval {
  int found[kSizeBins][kCalcBins] = {};
  int total[kSizeBins][kCalcBins] = {};
  int fillets = 0, not_inspected = 0, unmatched_truth_fillets = 0;
  int clean_fillets = 0, clean_rejected = 0, clean_not_inspected = 0;
  int bony_fillets = 0, bony_rejected = 0;
  // Fillets holding a calcified fragment >= 2 mm, and of them those passed down the line
  // (what a plant's customers would find): a miss in a fillet rejected for another detection
  // or by the fail-safe did not pass.
  int calcified_fillets = 0, calcified_passed = 0;
  int false_fragments = 0;                     // detected bones that match no true bone
  ErrorAccumulator position{1e-3, 100.0};      // mm
  double resid_mean_dn = 0, resid_std_dn = 0;  // pooled over inspected fillets
  long resid_pixels = 0;
  // With an EdgeMap: detections matching no bone by distance to the meat's edge (< 1 mm,
  // 1-3 mm, farther), and calcified fragments >= 2 mm within 3 mm of the edge (or on meat
  // under 6 mm: flaps) against the rest.
  int false_by_edge[3] = {0, 0, 0};
  int found_edge = 0, total_edge = 0, found_inner = 0, total_inner = 0;
  // Calcified fragments >= 2 mm by shape: found / present.
  std::vector<std::pair<std::string, std::pair<int, int>>> by_shape;
  std::vector<MissedFragment> missed;  // calcified fragments >= 2 mm not found
  std::vector<JudgedFragment> judged;  // every bone fragment

  double recall_calcified_2mm() const;  // calcified fragments >= 2 mm
  double false_reject_rate() const;     // clean fillets rejected for any reason
};

// Adds one lane's truth and results into `e` (call per lane, then finish()).
void add_lane(DetectionEval& e, const std::vector<TruthFragment>& frags,
              const std::vector<TruthFillet>& fillets, const RecordSet& results,
              const EdgeMap* edges = nullptr);
void finish(DetectionEval& e);

// The misses, one line each ("lane 2 fillet 25: 2.2 mm compact, calcification 0.90, under
// 20.8 mm of meat, 5.0 mm from the edge", and where measured "; found at 0.76 of the
// round thresholds, where the learned models imply 0.46 % false rejects"), and a summary by where
// they lie ("3 under 25 mm of meat or more, 1 within 3 mm of the edge, 0 elsewhere").
std::string missed_lines(const DetectionEval& e);
std::string missed_summary(const DetectionEval& e);

std::string detection_table(const DetectionEval& ours, const DetectionEval& baseline, int bits);
std::string detection_json(const DetectionEval& ours, const DetectionEval& baseline, int bits);

}  // namespace rangex
