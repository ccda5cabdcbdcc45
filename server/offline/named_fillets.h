// The fillets a failed learning named as bone-like, checked against a simulated recording's
// truth the way a plant checks them by hand: one whose fillet holds no bone is clean
// (cartilage, say, which one energy takes for bone) and goes back into the learning
// (`learn --keep`); one that holds bone, or that no fillet of the truth explains, stays out.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "offline/detection_eval.h"

namespace rangex {

struct NamedFillet {
  int lane = 0;
  int64_t id = 0;
  double belt_mm = 0;  // the belt position of its image's first row
};

struct NamedFilletCheck {
  std::vector<NamedFillet> clean, bony;  // bony: holds bone, or no truth fillet there
  std::string notes;                     // a line for each, saying why
};

// `truth`: the fillets of one lane (`lane`) of the learning recording; a named fillet of
// another lane has no truth here and stays out.
NamedFilletCheck check_named_fillets(const std::vector<NamedFillet>& named,
                                     const std::vector<TruthFillet>& truth, int lane);

// "LANE:ID,..." of the clean ones, as `learn --keep` reads them.
std::string keep_list(const std::vector<NamedFillet>& fillets);

}  // namespace rangex
