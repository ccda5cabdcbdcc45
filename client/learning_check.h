// A failed learning handled as a plant would handle it. The learning names fillets that
// hold something like bone; the plant checks each by hand: one that holds bone stays out
// (what `learn --force` does), one found clean (cartilage, say, which one energy takes for
// bone) goes back in (`learn --keep`), so the thresholds learn that product as it is. The
// evaluation matrix checks against the learning recording's truth instead of by hand.
#pragma once
#include <string>
#include <vector>

namespace rangex::cli {

struct LearningCheck {
  int named = 0;  // fillets the learnings named, each counted once
  int kept = 0;   // of those, found clean by the truth and learned again with
  int bony = 0;   // of those, holding bone by the truth (left out)
};

// Runs `learn LEARN_REC --out OUT EXTRA... --force` (EXTRA: --calibration, --check,
// --version, --config), reads the report (OUT with the extension .report/learn.json) and,
// when it named fillets that LEARN_REC's truth (one lane) says hold no bone, learns again
// keeping them; up to three rounds, as long as a round names fillets not checked before.
// The log says what was kept and why; the final learning's verdict is in its report.
LearningCheck learn_as_a_plant_would(const std::string& log, const std::string& learn_rec,
                                     const std::string& out, const std::vector<std::string>& extra);

}  // namespace rangex::cli
