// The figures a plant judges detection by, every fillet of an evaluation pooled, held
// against the targets rangex is accepted by (docs/inspection.md): clean fillets rejected (<= 0.5 %,
// and Wilson's upper 95 % bound <= 1.5 %, so that a run too small to tell says "not shown" rather
// than "met"), detections matching no bone (<= 0.02 a fillet), and recall of calcified fragments >=
// 2 mm
// (>= 99 %) on plants without needles, rib plates or cartilage. One energy cannot tell thin
// bone from cartilage, and needles and rib plates hold little bone along the ray: on a plant
// with them the recall is reported, not judged, and the reason named.
#pragma once
#include <string>

namespace rangex {

// Wilson's 95 % interval of k successes in n, as fractions ({0, 1} when n is 0).
struct Interval {
  double lo = 0, hi = 1;
};
Interval wilson95(int k, int n);

struct AcceptanceTargets {
  double false_reject = 0.005;        // clean fillets rejected
  double false_reject_upper = 0.015;  // the upper 95 % bound of that
  double no_bone_per_fillet = 0.02;   // detections matching no bone
  double recall = 0.99;               // calcified fragments >= 2 mm
};

// What an evaluation counted, pooled over its runs.
struct AcceptanceCounts {
  int clean_rejected = 0, clean = 0;  // clean fillets (no bone at all) and those rejected
  int no_bone = 0, fillets = 0;       // detections matching no bone, fillets inspected
  int found = 0, present = 0;         // calcified fragments >= 2 mm
  // What the recall target leaves out: calcified needles and rib plates >= 2 mm, and pieces
  // of cartilage or tendon, as the truth holds them.
  int needles = 0, ribs = 0, cartilage = 0;
};

struct Acceptance {
  double false_reject = 0, no_bone_per_fillet = 0, recall = 0;
  Interval false_reject_ci, recall_ci;
  bool false_rejects_met = false;  // the rate and its upper bound both within target
  bool no_bone_met = false;
  bool recall_judged = false;  // no needles, rib plates or cartilage in the plant
  bool recall_met = false;     // judged and within target
  std::string recall_exempt;   // why not judged: "needles, cartilage", say ("" when judged)
  // Every figure judged is met; recall, where it is judged, shown and met.
  bool met() const {
    return false_rejects_met && no_bone_met && (recall_exempt.empty() ? recall_met : true);
  }
};

Acceptance judge_acceptance(const AcceptanceCounts& c, const AcceptanceTargets& t = {});

// One paragraph: each figure with its count, interval and verdict, e.g.
// "clean fillets rejected 0/306 = 0.00 % [0.00-1.24 %]: met (<= 0.5 %, bound <= 1.5 %)".
std::string acceptance_text(const AcceptanceCounts& c, const Acceptance& a,
                            const AcceptanceTargets& t = {});

}  // namespace rangex
