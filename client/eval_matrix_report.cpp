// The matrix's report: its text (the variants' tables, the learned rows, the bone runs and
// the acceptance targets) and its JSON.
#include "eval_matrix_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/json_text.h"
#include "core/learned_detection.h"
#include "eval_steps.h"
#include "offline/acceptance.h"
#include "offline/fragment_chance.h"
#include "offline/miss_margin.h"

namespace rangex::cli {

namespace {

std::string table(const std::vector<MatrixRow>& rows, bool held_out) {
  std::ostringstream os;
  char b[512];
  std::snprintf(b, sizeof b,
                "%-19s %7s %7s %6s | %8s %7s %7s %7s | %7s %6s %9s %6s %6s | %8s %7s\n", "variant",
                "thick", "bias", "resid", "recall", "needle", "edge", "posit.", "f.rej", "n.i.",
                "f.frag/f", "<1mm", "1-3mm", "xr:rec", "xr:frej");
  os << b;
  for (const MatrixRow& r : rows) {
    if (r.held_out != held_out || !r.failed.empty()) continue;
    const DetectionEval& e = r.ours;
    std::snprintf(b, sizeof b,
                  "%-19s %7.3f %+7.3f %6.1f | %7.1f%% %7s %7s %7.3f | %6.1f%% %6d %9.3f %6d %6d | "
                  "%7.1f%% %6.1f%%\n",
                  r.name.c_str(), r.thickness.mean_abs, r.thickness.bias, e.resid_std_dn,
                  100 * e.recall_calcified_2mm(), shape_recall(e, "needle").c_str(),
                  (std::to_string(e.found_edge) + "/" + std::to_string(e.total_edge)).c_str(),
                  e.position.stats().mean_abs, 100 * e.false_reject_rate(), e.not_inspected,
                  e.fillets ? double(e.false_fragments) / e.fillets : 0.0, e.false_by_edge[0],
                  e.false_by_edge[1], 100 * r.base.recall_calcified_2mm(),
                  100 * r.base.false_reject_rate());
    os << b;
  }
  return os.str();
}

std::string learned_table(const std::vector<MatrixRow>& rows, bool held_out) {
  std::ostringstream os;
  char b[512];
  std::snprintf(b, sizeof b, "%-19s %5s %4s | %13s %7s | %11s %9s %9s | %15s %8s | %6s %15s %s\n",
                "variant", "learn", "flag", "recall [95%]", "needle", "f.rej", "[95%]", "f.frag/f",
                "clean: f.rej", "[95%]", "bands", "stated (pieces)",
                "sensitivity (learning fillets)");
  os << b;
  for (const MatrixRow& r : rows) {
    if (r.held_out != held_out || !r.learned_run) continue;
    const DetectionEval& e = r.learned;
    int k = 0, n = 0;
    calcified_2mm(e, k, n);
    const std::string clean = r.frr_fillets ? std::to_string(r.frr_rejected) + "/" +
                                                  std::to_string(r.frr_fillets) + " (" +
                                                  std::to_string(r.frr_fragments) + " bone)"
                                            : "-";
    const std::string stated = std::to_string(r.stated_held) + "/" + std::to_string(r.stated) +
                               " (" + std::to_string(r.stated_found) + "/" +
                               std::to_string(r.stated_injected) + ")";
    std::snprintf(
        b, sizeof b,
        "%-19s %5s %4d | %5.1f%% %6s %7s | %4d/%-4d %10s %9.3f | %15s %8s | %2d/%-3d %15s %s\n",
        r.name.c_str(),
        !r.learn_ok    ? "FAIL"
        : r.check.kept ? "kept"
                       : "ok",
        r.check.named, n ? 100.0 * k / n : 0.0, interval(k, n).c_str(),
        shape_recall(e, "needle").c_str(), e.clean_rejected, e.clean_fillets,
        interval(e.clean_rejected, e.clean_fillets).c_str(),
        e.fillets ? double(e.false_fragments) / e.fillets : 0.0, clean.c_str(),
        interval(r.frr_rejected, r.frr_fillets).c_str(), r.claims_held, r.claims, stated.c_str(),
        r.sensitivity.empty() ? "-" : r.sensitivity.front().c_str());
    os << b;
  }
  return os.str();
}

// The misses of `e` as JSON objects, comma-separated; `seed` >= 0 names the bone run's part.
std::string missed_json(const DetectionEval& e, long seed) {
  std::ostringstream os;
  for (size_t q = 0; q < e.missed.size(); ++q) {
    const MissedFragment& m = e.missed[q];
    os << (q ? ", " : "") << "{";
    if (seed >= 0) os << "\"seed\": " << seed << ", ";
    os << "\"fillet\": " << m.fillet << ", \"shape\": \"" << m.shape
       << "\", \"size_mm\": " << m.size_mm << ", \"calcification\": " << m.calcification
       << ", \"volume_mm3\": " << m.volume_mm3 << ", \"meat_mm\": " << m.meat_mm
       << ", \"edge_mm\": " << m.edge_mm << ", \"found_at\": " << m.found_at
       << ", \"frr_at\": " << m.frr_at << ", \"margin_statistic\": \""
       << (m.margin_stat >= 0 ? statistic_name(m.margin_stat) : "every")
       << "\", \"chance\": " << m.chance.chance << ", \"response\": " << m.chance.response
       << ", \"chance_threshold\": " << m.chance.threshold << ", \"fillet_decision\": \""
       << m.fillet_decision << "\"}";
  }
  return os.str();
}

// What the calcified fragments >= 2 mm of the plant and the bone run allow at the learned
// thresholds (offline/fragment_chance.h): their chances summed, over `measured` of them.
double bone_allows(const MatrixRow& r, int& measured) {
  double sum = 0;
  measured = 0;
  auto add = [&](const DetectionEval& e) {
    int m = 0;
    const double mean = expected_recall(e, m);
    if (m > 0) sum += mean * m, measured += m;
  };
  add(r.learned);
  for (const BonePart& p : r.bones) add(p.eval);
  return sum;
}

// Each calcified fragment >= 2 mm whose chance was measured (offline/fragment_chance.h),
// with its part's seed (-1: the plant's).
std::string chances_json(const DetectionEval& e, long seed, bool& first) {
  std::ostringstream os;
  for (const JudgedFragment& j : e.judged) {
    const FragmentChance& c = j.chance;
    if (c.chance < 0) continue;
    os << (first ? "" : ", ") << "{\"seed\": " << seed << ", \"fillet\": " << j.fillet
       << ", \"size_mm\": " << j.size_mm << ", \"volume_mm3\": " << j.volume_mm3
       << ", \"calcification\": " << j.calcification << ", \"meat_mm\": " << j.meat_mm
       << ", \"found\": " << (j.found ? "true" : "false") << ", \"statistic\": \""
       << statistic_name(c.stat) << "\", \"response\": " << c.response
       << ", \"observed\": " << c.observed << ", \"threshold\": " << c.threshold
       << ", \"chance\": " << c.chance << "}";
    first = false;
  }
  return os.str();
}

// The bone run of each variant that had one: recall pooled with the plant's, by shape, the
// clean fillets among them rejected, detections of no bone, and its misses.
std::string bone_run_text(const std::vector<MatrixRow>& rows) {
  std::ostringstream os;
  char b[512];
  for (const MatrixRow& r : rows) {
    if (r.bones.empty()) continue;
    const BoneRunTotals t = pooled(r.bones);
    int k = 0, n = 0;
    calcified_2mm(r.learned, k, n);
    k += t.found, n += t.present;
    std::snprintf(b, sizeof b,
                  "%s%s: %d fillets: calcified >= 2 mm %d/%d; with the plant's %d/%d = %.1f %% "
                  "[%s %%]; clean fillets rejected %d/%d [%s %%]; detections of no bone %.3f a "
                  "fillet\n",
                  r.name.c_str(), r.held_out ? " (held out)" : "", t.fillets, t.found, t.present, k,
                  n, n ? 100.0 * k / n : 0.0, interval(k, n).c_str(), t.clean_rejected, t.clean,
                  interval(t.clean_rejected, t.clean).c_str(),
                  t.fillets ? double(t.false_fragments) / t.fillets : 0.0);
    os << b;
    // What a plant's customers would find: fillets holding such bone that passed.
    const int cf = t.calcified_fillets + r.learned.calcified_fillets,
              cp = t.calcified_passed + r.learned.calcified_passed;
    std::snprintf(b, sizeof b,
                  "  fillets holding calcified >= 2 mm passed down the line (plant and bone "
                  "run): %d of %d [%s %%]\n",
                  cp, cf, interval(cp, cf).c_str());
    os << b << "  by shape (bone run):";
    for (const auto& [shape, fp] : t.by_shape)
      os << " " << shape << " " << fp.first << "/" << fp.second;
    int measured = 0;
    const double sum = bone_allows(r, measured);
    if (measured > 0) {
      std::snprintf(b, sizeof b,
                    "\n  were each fragment's bone a sphere (one more injected where it lies, its "
                    "chance at the thresholds Phi(E - T)), their chances would sum to %.1f of "
                    "%d = %.1f %%",
                    sum, measured, 100 * sum / measured);
      os << b;
    }
    os << "\n" << prefixed(bone_run_missed_lines(r.bones), "  ");
  }
  return os.str();
}

// The run's fillets pooled: the plant's and its clean and bone runs, with the thresholds
// learned.
AcceptanceCounts acceptance_counts(const MatrixRow& r) {
  AcceptanceCounts c;
  const DetectionEval& e = r.learned;
  calcified_2mm(e, c.found, c.present);
  c.clean_rejected = e.clean_rejected + r.frr_rejected, c.clean = e.clean_fillets + r.frr_fillets;
  c.no_bone = e.false_fragments + r.frr_fragments, c.fillets = e.fillets + r.frr_fillets;
  auto shapes = e.by_shape;
  if (!r.bones.empty()) {
    const BoneRunTotals t = pooled(r.bones);
    c.found += t.found, c.present += t.present;
    c.clean_rejected += t.clean_rejected, c.clean += t.clean;
    c.no_bone += t.false_fragments, c.fillets += t.fillets;
    shapes.insert(shapes.end(), t.by_shape.begin(), t.by_shape.end());
  }
  for (const auto& [shape, fp] : shapes) {
    if (shape == "needle") c.needles += fp.second;
    if (shape == "rib") c.ribs += fp.second;
  }
  c.cartilage = r.cartilage;
  return c;
}

std::string acceptance_section(const std::vector<MatrixRow>& rows) {
  std::ostringstream os;
  for (const MatrixRow& r : rows) {
    if (!r.learned_run || !r.failed.empty()) continue;
    const AcceptanceCounts c = acceptance_counts(r);
    const Acceptance a = judge_acceptance(c);
    os << r.name << (r.held_out ? " (held out)" : "") << ": " << (a.met() ? "met" : "not met")
       << "\n"
       << prefixed(acceptance_text(c, a), "  ");
  }
  return os.str();
}

}  // namespace

namespace {

using ShapeCounts = std::vector<std::pair<std::string, std::pair<int, int>>>;

// {"shape": [found, present], ...}
std::string shape_counts_json(const ShapeCounts& by_shape) {
  std::ostringstream os;
  os << "{";
  for (size_t k = 0; k < by_shape.size(); ++k)
    os << (k ? ", " : "") << "\"" << by_shape[k].first << "\": [" << by_shape[k].second.first
       << ", " << by_shape[k].second.second << "]";
  os << "}";
  return os.str();
}

// A variant's run at the plant file's fixed thresholds and the X-ray-only baseline's: the
// fields from "held_out" to "minutes".
std::string fixed_json(const MatrixRow& r) {
  const DetectionEval& e = r.ours;
  std::ostringstream os;
  os << "\"held_out\": " << (r.held_out ? "true" : "false")
     << ", \"thickness_mean_abs_mm\": " << r.thickness.mean_abs
     << ", \"thickness_bias_mm\": " << r.thickness.bias
     << ", \"residual_std_dn\": " << e.resid_std_dn
     << ", \"recall_calcified_ge_2mm\": " << e.recall_calcified_2mm() << ", \"recall_edge\": ["
     << e.found_edge << ", " << e.total_edge << "]"
     << ", \"recall_inner\": [" << e.found_inner << ", " << e.total_inner << "]"
     << ", \"recall_by_shape\": " << shape_counts_json(e.by_shape)
     << ", \"false_reject_rate\": " << e.false_reject_rate()
     << ", \"clean_fillets\": " << e.clean_fillets << ", \"fillets\": " << e.fillets
     << ", \"not_inspected\": " << e.not_inspected << ", \"false_fragments\": " << e.false_fragments
     << ", \"false_fragments_by_edge\": [" << e.false_by_edge[0] << ", " << e.false_by_edge[1]
     << ", " << e.false_by_edge[2] << "]"
     << ", \"position_mean_mm\": " << e.position.stats().mean_abs
     << ", \"baseline_recall_calcified_ge_2mm\": " << r.base.recall_calcified_2mm()
     << ", \"baseline_false_reject_rate\": " << r.base.false_reject_rate()
     << ", \"minutes\": " << r.minutes;
  return os.str();
}

// The bone run's parts pooled, with the fragments each missed (by its seed).
std::string bone_run_json(const MatrixRow& r) {
  const BoneRunTotals t = pooled(r.bones);
  int measured = 0;
  const double allows = bone_allows(r, measured);
  std::ostringstream os;
  os << "{\"fillets\": " << t.fillets << ", \"recall_calcified_ge_2mm\": [" << t.found << ", "
     << t.present << "], \"recall_by_shape\": " << shape_counts_json(t.by_shape)
     << ", \"bone_allows\": [" << allows << ", " << measured << "]"
     << ", \"calcified_fillets_passed\": [" << t.calcified_passed << ", " << t.calcified_fillets
     << "], \"false_rejects\": [" << t.clean_rejected << ", " << t.clean
     << "], \"false_fragments\": " << t.false_fragments << ", \"missed\": [";
  bool first = true;
  for (const BonePart& b : r.bones)
    if (!b.eval.missed.empty())
      os << (first ? "" : ", ") << missed_json(b.eval, b.seed), first = false;
  os << "]}";
  return os.str();
}

// The targets, judged over every fillet of the run pooled.
std::string acceptance_json(const MatrixRow& r) {
  const AcceptanceCounts c = acceptance_counts(r);
  const Acceptance a = judge_acceptance(c);
  std::ostringstream os;
  os << "{\"met\": " << (a.met() ? "true" : "false") << ", \"false_rejects\": [" << c.clean_rejected
     << ", " << c.clean << "], \"false_reject_upper\": " << a.false_reject_ci.hi
     << ", \"false_rejects_met\": " << (a.false_rejects_met ? "true" : "false")
     << ", \"no_bone\": [" << c.no_bone << ", " << c.fillets
     << "], \"no_bone_met\": " << (a.no_bone_met ? "true" : "false")
     << ", \"recall_calcified_ge_2mm\": [" << c.found << ", " << c.present
     << "], \"recall_judged\": " << (a.recall_judged ? "true" : "false")
     << ", \"recall_met\": " << (a.recall_met ? "true" : "false")
     << ", \"recall_exempt\": " << json_text(a.recall_exempt) << ", \"needles\": " << c.needles
     << ", \"ribs\": " << c.ribs << ", \"cartilage\": " << c.cartilage << "}";
  return os.str();
}

// The run with the thresholds learned from the variant's own clean fillets: the plant's
// fillets, the learning's claims and their checks, the clean run, the bone run, the targets.
std::string learned_json(const MatrixRow& r) {
  const DetectionEval& l = r.learned;
  int k = 0, n = 0;
  calcified_2mm(l, k, n);
  std::ostringstream os;
  os << "{\"ok\": " << (r.learn_ok ? "true" : "false")
     << ", \"learning_fillets\": " << r.learn_fillets << ", \"flagged\": " << r.learn_flagged
     << ", \"named\": " << r.check.named << ", \"kept_checked_clean\": " << r.check.kept
     << ", \"left_out_bony\": " << r.check.bony << ", \"recall_calcified_ge_2mm\": [" << k << ", "
     << n << "], \"recall_by_shape\": " << shape_counts_json(l.by_shape) << ", \"false_rejects\": ["
     << l.clean_rejected << ", " << l.clean_fillets << "], \"not_inspected\": " << l.not_inspected
     << ", \"false_fragments\": " << l.false_fragments << ", \"fillets\": " << l.fillets
     << ", \"claims\": " << r.claims << ", \"claims_held\": " << r.claims_held
     << ", \"claims_contradicted\": " << r.claims_contradicted << ", \"stated\": " << r.stated
     << ", \"stated_held\": " << r.stated_held << ", \"stated_pieces\": [" << r.stated_found << ", "
     << r.stated_injected << "]"
     << ", \"clean_run\": {\"fillets\": " << r.frr_fillets << ", \"rejected\": " << r.frr_rejected
     << ", \"not_inspected\": " << r.frr_not_inspected << ", \"fragments\": " << r.frr_fragments
     << ", \"drift\": " << drift_json(r.drift) << "}"
     << ", \"sensitivity\": [";
  for (size_t q = 0; q < r.sensitivity.size(); ++q)
    os << (q ? ", " : "") << json_text(r.sensitivity[q]);
  os << "], \"missed\": [" << missed_json(l, -1) << "]";
  if (r.claims_measured) os << ", \"claims_on_fragments\": " << claims_json(r.fragment_claims);
  bool first = true;
  os << ", \"fragment_chances\": [" << chances_json(r.learned, -1, first);
  for (const BonePart& b : r.bones) os << chances_json(b.eval, b.seed, first);
  os << "]";
  if (!r.bones.empty()) os << ", \"bone_run\": " << bone_run_json(r);
  os << ", \"acceptance\": " << acceptance_json(r) << "}";
  return os.str();
}

}  // namespace

std::string matrix_json(const std::vector<MatrixRow>& rows) {
  std::ostringstream os;
  os << "{\"variants\": [";
  for (size_t i = 0; i < rows.size(); ++i) {
    const MatrixRow& r = rows[i];
    os << (i ? ",\n  " : "\n  ");
    if (!r.failed.empty()) {
      os << json_dump({{"name", r.name}, {"failed", r.failed}});
      continue;
    }
    os << "{\"name\": " << json_text(r.name) << ", " << fixed_json(r);
    if (r.learned_run) os << ", \"learned\": " << learned_json(r);
    os << "}";
  }
  os << "\n]}\n";
  return os.str();
}

// The matrix's report over the variants run so far.
std::string matrix_text(const std::vector<MatrixRow>& rows, const MatrixOptions& mo) {
  const int fillets = mo.fillets;
  const long seed = mo.seed;
  std::ostringstream os;
  os << "plant variants, each calibrated from its own scenes (" << fillets << " fillets each, seed "
     << seed << "):\n"
     << "thick/bias: thickness mean |error| and bias, mm; resid: how rough the plant is, the "
        "residual I - P's standard deviation in DN (the dissertation's real fillets: 29.6); "
        "recall: calcified fragments >= 2 mm;"
        " needle, edge: the same for needles and within 3 mm of the edge or on meat under 6 "
        "mm (found/present); posit.: position error, mm; f.rej: clean fillets rejected; n.i.: "
        "fillets not inspected; f.frag/f: detections matching no bone per fillet, <1mm / "
        "1-3mm of them from the meat's edge; xr: the X-ray-only baseline\n\n"
     << table(rows, false);
  const bool held_out =
      std::any_of(rows.begin(), rows.end(), [](const MatrixRow& r) { return r.held_out; });
  if (held_out) os << "\nheld out (never tuned on):\n" << table(rows, true);
  if (mo.learn_fillets > 0) {
    os << "\nwith thresholds learned from " << mo.learn_fillets
       << " clean fillets of each variant (another seed; claims checked on " << mo.check_fillets
       << " more): recall of calcified >= 2 mm with its 95 % interval; f.rej: clean fillets "
          "rejected with the 95 % interval in %; bands: sensitivity claims by thickness band "
          "held on the check fillets; stated: the report's sentences held there (their pieces "
          "found); flag: fillets the learning named as bone-like, each checked against the "
          "truth as a plant checks them by hand (kept: found clean and learned again with "
          "them, learn --keep; bony ones left out)\n\n"
       << learned_table(rows, false);
    if (held_out) os << "\nheld out (never tuned on):\n" << learned_table(rows, true);
    if (std::any_of(rows.begin(), rows.end(),
                    [](const MatrixRow& r) { return !r.claims_not_held.empty(); })) {
      os << "\nclaims by band not held on the check fillets (a band's claim rests on 10-40 "
            "pieces there, which fall one or two short of its rate by chance about as often "
            "as not; contradicted: so few found in under 5 % of checks of a true claim):\n";
      for (const MatrixRow& r : rows)
        if (!r.claims_not_held.empty()) {
          os << r.name << ": " << r.claims_not_held.size() << " of " << r.claims << " not held, "
             << r.claims_contradicted << " contradicted\n";
          for (const std::string& t : r.claims_not_held) os << "  " << t << "\n";
        }
    }
    if (std::any_of(rows.begin(), rows.end(),
                    [](const MatrixRow& r) { return !r.drift_sentence.empty(); })) {
      os << "\nthe lane's drift monitor over the clean run (its passed fillets in order; "
            "a warning when the last 200 imply more than twice the target):\n";
      for (const MatrixRow& r : rows)
        if (!r.drift_sentence.empty())
          os << r.name << ":\n" << prefixed(r.drift_sentence, "  ") << "\n";
    }
    os << "\nwhere the learned thresholds missed calcified fragments >= 2 mm:\n";
    for (const MatrixRow& r : rows)
      if (r.learned_run)
        os << r.name << ": " << missed_summary(r.learned) << "\n"
           << prefixed(missed_lines(r.learned), "  ");
    if (mo.bone_fillets > 0)
      os << "\nthe bone run: " << mo.bone_fillets
         << " more fillets of each variant's plant, bones and all (seeds " << seed + 10000
         << ", +100 a part of " << mo.frr_part
         << "), inspected with the learned thresholds and judged against their truth; the "
            "interval is Wilson's 95 %, pooled with the plant's fragments:\n"
         << bone_run_text(rows);
    os << "\nthe report's sphere claims on each variant's own fragments (the plant's"
       << (mo.bone_fillets > 0 ? " and the bone run's" : "")
       << "): a compact fragment is covered where the claim for its band of meat is a sphere "
          "holding no more bone than it (volume x its attenuation over the meat, against the "
          "test piece's); the claim says 95 %:\n";
    for (const MatrixRow& r : rows)
      if (r.claims_measured) os << claims_text(r.name, r.fragment_claims);
    os << "\nagainst the acceptance targets, every fillet of this run pooled: the plant's, "
          "the clean run's and the bone run's, with the learned thresholds; Wilson's 95 % "
          "intervals. Recall is judged on plants without needles, rib plates or cartilage, "
          "and reported on the others:\n"
       << acceptance_section(rows);
  }
  for (const MatrixRow& r : rows)
    if (!r.failed.empty()) os << "\nfailed: " << r.name << ": " << r.failed << "\n";
  return os.str();
}

}  // namespace rangex::cli
