#include "offline/acceptance.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rangex {

Interval wilson95(int k, int n) {
  if (n <= 0) return {};
  const double z = 1.959964, p = double(k) / n, d = 1 + z * z / n;
  const double c = (p + z * z / (2 * n)) / d,
               h = z * std::sqrt(p * (1 - p) / n + z * z / (4.0 * n * n)) / d;
  return {std::max(0.0, c - h), std::min(1.0, c + h)};
}

Acceptance judge_acceptance(const AcceptanceCounts& c, const AcceptanceTargets& t) {
  Acceptance a;
  a.false_reject = c.clean ? double(c.clean_rejected) / c.clean : 0;
  a.false_reject_ci = wilson95(c.clean_rejected, c.clean);
  // No clean fillet is no evidence: the bound of 0 in 0 is 1.
  a.false_rejects_met = c.clean > 0 && a.false_reject <= t.false_reject &&
                        a.false_reject_ci.hi <= t.false_reject_upper;
  a.no_bone_per_fillet = c.fillets ? double(c.no_bone) / c.fillets : 0;
  a.no_bone_met = c.fillets > 0 && a.no_bone_per_fillet <= t.no_bone_per_fillet;
  a.recall = c.present ? double(c.found) / c.present : 0;
  a.recall_ci = wilson95(c.found, c.present);
  for (const auto& [n, what] : {std::pair{c.needles, "needles"}, std::pair{c.ribs, "rib plates"},
                                std::pair{c.cartilage, "cartilage"}})
    if (n > 0) a.recall_exempt += (a.recall_exempt.empty() ? "" : ", ") + std::string(what);
  a.recall_judged = a.recall_exempt.empty() && c.present > 0;
  a.recall_met = a.recall_judged && a.recall >= t.recall;
  return a;
}

std::string acceptance_text(const AcceptanceCounts& c, const Acceptance& a,
                            const AcceptanceTargets& t) {
  char b[256];
  std::string s;
  std::snprintf(b, sizeof b, "clean fillets rejected %d/%d = %.2f %% [%.2f-%.2f %%]: %s",
                c.clean_rejected, c.clean, 100 * a.false_reject, 100 * a.false_reject_ci.lo,
                100 * a.false_reject_ci.hi,
                a.false_rejects_met               ? "met"
                : c.clean == 0                    ? "not shown (no clean fillet)"
                : a.false_reject > t.false_reject ? "not met"
                                                  : "not shown (too few fillets for the bound)");
  s += b;
  std::snprintf(b, sizeof b, " (<= %.1f %%, bound <= %.1f %%)\n", 100 * t.false_reject,
                100 * t.false_reject_upper);
  s += b;
  std::snprintf(b, sizeof b,
                "detections of no bone %d in %d fillets = %.3f a fillet: %s (<= %.2f)\n", c.no_bone,
                c.fillets, a.no_bone_per_fillet,
                a.no_bone_met    ? "met"
                : c.fillets == 0 ? "not shown (no fillet)"
                                 : "not met",
                t.no_bone_per_fillet);
  s += b;
  std::snprintf(b, sizeof b, "calcified >= 2 mm found %d/%d = %.1f %% [%.1f-%.1f %%]: ", c.found,
                c.present, 100 * a.recall, 100 * a.recall_ci.lo, 100 * a.recall_ci.hi);
  s += b;
  if (a.recall_judged) {
    std::snprintf(b, sizeof b, "%s (>= %.0f %%)\n", a.recall_met ? "met" : "not met",
                  100 * t.recall);
    s += b;
  } else if (c.present == 0) {
    s += "not shown (no such fragment)\n";
  } else {
    s += "reported, not judged: the plant holds " + a.recall_exempt + "\n";
  }
  return s;
}

}  // namespace rangex
