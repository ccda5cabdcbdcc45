// eval-matrix --bones N: N more fillets of a variant's plant, bones and all, inspected with
// the thresholds it learned and judged against their truth. A 60-fillet plant holds 11-18
// calcified fragments >= 2 mm, whose 95 % interval cannot tell 93 % from 99 %; this run
// can. Simulated and judged in parts, each scan dropped once judged (130 MB a fillet).
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "core/lane_config.h"
#include "core/recording.h"
#include "eval_steps.h"
#include "offline/detection_eval.h"

namespace rangex::cli {

struct BonePart {
  long seed = 0;
  DetectionEval eval;  // finished, its misses' margins measured where `margins` did
};

// The parts of `o` (bones and all: o.clean is ignored; o.rec "bone_rec", o.out "out_bones"),
// each judged against its truth on `lane`; `margins` measures its misses while the scan is
// there (every part: each fragment's chance is measured too).
std::vector<BonePart> run_bone_parts(
    PartRun o, const LaneConfig& lane,
    const std::function<void(DetectionEval&, const RecordingReader&)>& margins);

// The parts pooled: calcified fragments >= 2 mm found and present, clean fillets rejected
// of clean fillets, detections of no bone, fillets.
struct BoneRunTotals {
  int found = 0, present = 0, clean_rejected = 0, clean = 0, false_fragments = 0, fillets = 0;
  int calcified_fillets = 0, calcified_passed = 0;  // holding calcified >= 2 mm; passed
  std::vector<std::pair<std::string, std::pair<int, int>>> by_shape;  // calcified >= 2 mm
};
BoneRunTotals pooled(const std::vector<BonePart>& parts);

// Its misses, one line each, prefixed by their part's seed.
std::string bone_run_missed_lines(const std::vector<BonePart>& parts);

}  // namespace rangex::cli
