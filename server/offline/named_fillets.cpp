#include "offline/named_fillets.h"

#include <cstdio>

namespace rangex {

namespace {

// The truth fillet a named fillet starts in: its image's first row lies at the fillet's
// start give or take the margin the assembly adds (a few mm).
const TruthFillet* truth_fillet_at(const std::vector<TruthFillet>& fillets, double belt_mm) {
  constexpr double kMarginMm = 10;
  const TruthFillet* best = nullptr;
  double best_d = kMarginMm;
  for (const TruthFillet& f : fillets) {
    const double d = belt_mm < f.b_start ? f.b_start - belt_mm
                     : belt_mm > f.b_end ? belt_mm - f.b_end
                                         : 0.0;
    if (d <= best_d) best_d = d, best = &f;
  }
  return best;
}

}  // namespace

NamedFilletCheck check_named_fillets(const std::vector<NamedFillet>& named,
                                     const std::vector<TruthFillet>& truth, int lane) {
  NamedFilletCheck c;
  for (const NamedFillet& n : named) {
    const TruthFillet* t = n.lane == lane ? truth_fillet_at(truth, n.belt_mm) : nullptr;
    char b[200];
    if (t && t->bones == 0) {
      c.clean.push_back(n);
      std::snprintf(b, sizeof b,
                    "lane %d fillet %lld (belt %.0f mm): truth fillet %d, no bone: kept\n", n.lane,
                    (long long)n.id, n.belt_mm, t->fillet);
    } else {
      c.bony.push_back(n);
      if (t)
        std::snprintf(
            b, sizeof b,
            "lane %d fillet %lld (belt %.0f mm): truth fillet %d holds %d bone: left out\n", n.lane,
            (long long)n.id, n.belt_mm, t->fillet, t->bones);
      else
        std::snprintf(b, sizeof b,
                      "lane %d fillet %lld (belt %.0f mm): no truth fillet there: left out\n",
                      n.lane, (long long)n.id, n.belt_mm);
    }
    c.notes += b;
  }
  return c;
}

std::string keep_list(const std::vector<NamedFillet>& fillets) {
  std::string s;
  for (const NamedFillet& f : fillets)
    s += (s.empty() ? "" : ",") + std::to_string(f.lane) + ":" + std::to_string(f.id);
  return s;
}

}  // namespace rangex
