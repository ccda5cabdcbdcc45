#include "offline/detection_eval.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <sstream>

#include "core/error.h"
#include "core/learned_detection.h"

namespace rangex {

namespace {
// Rows of one of `fields` cells each (the current layout first, then older ones).
std::vector<std::vector<std::string>> csv_rows(const std::string& text,
                                               std::initializer_list<size_t> fields,
                                               const char* what) {
  std::vector<std::vector<std::string>> rows;
  std::stringstream in(text);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::vector<std::string> c;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ',')) c.push_back(cell);
    if (std::find(fields.begin(), fields.end(), c.size()) == fields.end())
      fail("truth ", what, ": expected ", *fields.begin(), " fields in '", line, "'");
    rows.push_back(std::move(c));
  }
  return rows;
}

int size_bin(double s) {
  return s < 2 ? 0 : s < 3 ? 1 : s < 5 ? 2 : 3;
}
}  // namespace

std::vector<TruthFragment> parse_truth_fragments(const std::string& text, int lane) {
  std::vector<TruthFragment> out;
  // fillet,kind,x_mm,b_mm,z_mm,xray_line,size_mm,calcification[,shape[,volume_mm3[,excess_mu,
  // meat_mu]]]
  for (const auto& c : csv_rows(text, {12, 10, 8, 9}, "fragments.csv"))
    out.push_back({lane, std::stoi(c[0]), c[1], std::stod(c[2]), std::stod(c[3]), std::stod(c[6]),
                   std::stod(c[7]), c.size() > 8 ? c[8] : "compact", std::stod(c[5]),
                   c.size() > 9 ? std::stod(c[9]) : -1.0, c.size() > 11 ? std::stod(c[10]) : -1.0,
                   c.size() > 11 ? std::stod(c[11]) : -1.0});
  return out;
}

std::vector<TruthFillet> parse_truth_fillets(const std::string& text, int lane) {
  std::vector<TruthFillet> out;
  for (const auto& c : csv_rows(text, {6}, "fillets.csv"))
    out.push_back({lane, std::stoi(c[0]), std::stod(c[2]), std::stod(c[3]), std::stoi(c[5])});
  return out;
}

namespace {
// The detector pixel whose ray passes x at mid-depth (about 10 mm up).
double pixel_of(const EdgeMap& m, double x_mm) {
  constexpr double kZ = 10;
  const double x_det = m.source_x_mm + (x_mm - m.source_x_mm) * (m.source_z_mm - m.detector_z_mm) /
                                           (m.source_z_mm - kZ);
  return (x_det - m.first_pixel_x_mm) / m.pitch_mm;
}
}  // namespace

double EdgeMap::thickness_mm(double x_mm, double xray_line) const {
  const int i = int(std::lround(pixel_of(*this, x_mm)));
  const int64_t n = std::lround(xray_line);
  if (!thickness || i < 0 || i >= pixels || n < 0 || n >= lines) return 0;
  return thickness[n * pixels + i];
}

double EdgeMap::distance_mm(double x_mm, double xray_line) const {
  constexpr double kReach = 5;
  if (!thickness) return kReach;
  const int i0 = int(std::lround(pixel_of(*this, x_mm))), n0 = int(std::lround(xray_line));
  const int ri = int(std::ceil(kReach / pitch_mm)), rn = int(std::ceil(kReach / step_mm));
  double best = kReach;
  for (int dn = -rn; dn <= rn; ++dn)
    for (int di = -ri; di <= ri; ++di) {
      const int64_t n = n0 + dn;
      const int i = i0 + di;
      if (n < 0 || n >= lines || i < 0 || i >= pixels) continue;
      if (thickness[n * pixels + i] >= 0.5) continue;  // meat
      best = std::min(best, std::hypot(di * pitch_mm, dn * step_mm));
    }
  return best;
}

void add_lane(DetectionEval& e, const std::vector<TruthFragment>& frags,
              const std::vector<TruthFillet>& truth_fillets, const RecordSet& res,
              const EdgeMap* edges) {
  // Which detected fillet (by belt range) holds each true fillet; rejects count for all.
  auto overlapping = [&](double b0, double b1) {
    std::vector<const FilletRecord*> v;
    for (const FilletRecord& f : res.fillets)
      if (f.y1_mm > b0 && f.y0_mm < b1) v.push_back(&f);
    return v;
  };
  for (const FilletRecord& f : res.fillets) {
    ++e.fillets;
    if (f.decision == "not_inspected") ++e.not_inspected;
    if (f.decision != "not_inspected" && f.pixels > 0) {
      // Pool mean and variance of I - P over pixels.
      const double n = f.pixels;
      e.resid_mean_dn += n * f.resid_mean_dn;
      e.resid_std_dn += n * (f.resid_std_dn * f.resid_std_dn + f.resid_mean_dn * f.resid_mean_dn);
      e.resid_pixels += f.pixels;
    }
  }
  // The fillets holding a calcified fragment >= 2 mm.
  std::vector<int> calcified;
  for (const TruthFragment& t : frags)
    if (t.kind == "bone" && size_bin(t.size_mm) >= 1 && t.calcification >= kCalcified)
      calcified.push_back(t.fillet);
  for (const TruthFillet& t : truth_fillets) {
    const auto hits = overlapping(t.b_start, t.b_end);
    bool rejected = hits.empty(), not_inspected = hits.empty();
    for (const FilletRecord* f : hits) {
      rejected |= f->decision != "pass";
      not_inspected |= f->decision == "not_inspected";
    }
    e.unmatched_truth_fillets += hits.empty();
    if (std::find(calcified.begin(), calcified.end(), t.fillet) != calcified.end()) {
      ++e.calcified_fillets;
      e.calcified_passed += !rejected;
    }
    if (t.bones == 0) {
      ++e.clean_fillets;
      e.clean_rejected += rejected;
      e.clean_not_inspected += not_inspected;
    } else {
      ++e.bony_fillets;
      e.bony_rejected += rejected;
    }
  }
  std::vector<char> used(res.fragments.size(), 0);
  for (const TruthFragment& t : frags) {
    if (t.kind != "bone") continue;
    const int sb = size_bin(t.size_mm), cb = t.calcification >= kCalcified ? 1 : 0;
    ++e.total[sb][cb];
    const double tol = std::max(2.0, 0.5 * t.size_mm + 1.0);
    double best = 1e9;
    size_t best_i = 0;
    for (size_t i = 0; i < res.fragments.size(); ++i) {
      const FragmentRecord& d = res.fragments[i];
      if (d.kind != "bone" || d.lane != t.lane) continue;
      const double dist = std::hypot(d.x_mm - t.x_mm, d.y_mm - t.b_mm);
      if (dist < best) best = dist, best_i = i;
    }
    if (best <= tol) {
      ++e.found[sb][cb];
      used[best_i] = 1;
      e.position.add(best);
    }
    e.judged.push_back({t.lane, t.fillet, t.shape, t.size_mm, t.calcification, t.volume_mm3,
                        t.excess_mu, t.meat_mu,
                        edges ? edges->thickness_mm(t.x_mm, t.xray_line) : -1.0, best <= tol});
    e.judged.back().x_mm = t.x_mm, e.judged.back().b_mm = t.b_mm, e.judged.back().tol_mm = tol;
    if (sb >= 1 && cb == 1 && best > tol) {
      MissedFragment m{t.lane, t.fillet, t.shape, t.size_mm, t.calcification};
      // What became of its fillet: rejected for anything, the bone did not go down the line.
      for (const TruthFillet& tf : truth_fillets)
        if (tf.fillet == t.fillet)
          for (const FilletRecord* f : overlapping(tf.b_start, tf.b_end))
            if (m.fillet_decision.empty() || m.fillet_decision == "pass")
              m.fillet_decision = f->decision;
      m.volume_mm3 = t.volume_mm3;
      m.x_mm = t.x_mm, m.b_mm = t.b_mm, m.tol_mm = tol;
      if (edges) {
        m.meat_mm = edges->thickness_mm(t.x_mm, t.xray_line);
        m.edge_mm = edges->distance_mm(t.x_mm, t.xray_line);
      }
      e.missed.push_back(m);
    }
    if (sb >= 1 && cb == 1) {
      auto it = std::find_if(e.by_shape.begin(), e.by_shape.end(),
                             [&](const auto& s) { return s.first == t.shape; });
      if (it == e.by_shape.end()) it = e.by_shape.insert(e.by_shape.end(), {t.shape, {0, 0}});
      it->second.first += best <= tol, ++it->second.second;
      if (edges) {
        const bool edge = edges->distance_mm(t.x_mm, t.xray_line) < 3 ||
                          edges->thickness_mm(t.x_mm, t.xray_line) < 6;
        (edge ? e.found_edge : e.found_inner) += best <= tol;
        ++(edge ? e.total_edge : e.total_inner);
      }
    }
  }
  for (size_t i = 0; i < res.fragments.size(); ++i)
    if (res.fragments[i].kind == "bone" && !used[i]) {
      // A second detection of an already matched bone is not a false alarm.
      bool near_true = false;
      for (const TruthFragment& t : frags)
        if (t.kind == "bone" && t.lane == res.fragments[i].lane &&
            std::hypot(res.fragments[i].x_mm - t.x_mm, res.fragments[i].y_mm - t.b_mm) <=
                std::max(2.0, 0.5 * t.size_mm + 1.0))
          near_true = true;
      e.false_fragments += !near_true;
      if (!near_true && edges) {
        const FragmentRecord& d = res.fragments[i];
        const double dist =
            edges->distance_mm(d.x_mm, d.y_mm / edges->step_mm + edges->delay_lines);
        ++e.false_by_edge[dist < 1 ? 0 : dist < 3 ? 1 : 2];
      }
    }
}

void finish(DetectionEval& e) {
  if (e.resid_pixels > 0) {
    const double n = double(e.resid_pixels);
    const double mean = e.resid_mean_dn / n, m2 = e.resid_std_dn / n;
    e.resid_mean_dn = mean;
    e.resid_std_dn = std::sqrt(std::max(0.0, m2 - mean * mean));
  }
}

double DetectionEval::recall_calcified_2mm() const {
  int f = 0, t = 0;
  for (int s = 1; s < kSizeBins; ++s) f += found[s][1], t += total[s][1];
  return t ? double(f) / t : 0;
}

double DetectionEval::false_reject_rate() const {
  return clean_fillets ? double(clean_rejected) / clean_fillets : 0;
}

namespace {
// Where a miss lies, as the matrix's edge column counts it: at the edge (within 3 mm, or on
// meat under 6 mm: flaps), under thick meat (25 mm or more), or elsewhere; unknown without
// an EdgeMap.
enum MissPlace { kThick, kEdge, kElsewhere, kUnknown };
MissPlace miss_place(const MissedFragment& m) {
  if (m.meat_mm < 0) return kUnknown;
  if (m.edge_mm < 3 || m.meat_mm < 6) return kEdge;
  if (m.meat_mm >= 25) return kThick;
  return kElsewhere;
}
}  // namespace

namespace {
// What finding it would cost, when it was measured.
std::string margin_text(const MissedFragment& m) {
  char b[200] = "", rate[80] = "";
  const std::string which =
      m.margin_stat >= 0 ? statistic_name(m.margin_stat) + std::string(" ") : "";
  // The models' rate is a sum over bands and statistics: a bound that passes 1 where the
  // thresholds sink into clean meat's extremes.
  if (m.frr_at >= 0.5)
    std::snprintf(rate, sizeof rate,
                  ", where the learned models imply most clean fillets rejected");
  else if (m.frr_at >= 0)
    std::snprintf(rate, sizeof rate, ", where the learned models imply %.2f %% false rejects",
                  100 * m.frr_at);
  if (m.found_at > 0)
    std::snprintf(b, sizeof b, "; found at %.2f of the %sthresholds%s", m.found_at, which.c_str(),
                  rate);
  else if (m.found_at == 0)
    std::snprintf(b, sizeof b, "; not found at any fraction of the thresholds down to %.2f",
                  m.margin_floor);
  return b;
}

// What its bone could show (offline/fragment_chance.h).
std::string chance_text(const MissedFragment& m) {
  const FragmentChance& c = m.chance;
  if (c.chance < 0) return "";
  char b[200];
  std::snprintf(b, sizeof b,
                "; one more sphere of its bone there adds %.1f to the %s statistic (its own "
                "peak there: %.1f) against a threshold of %.1f: a chance of %.0f %%",
                c.response, statistic_name(c.stat), c.observed, c.threshold, 100 * c.chance);
  return b;
}
}  // namespace

std::string missed_lines(const DetectionEval& e) {
  std::string out;
  char b[256];
  for (const MissedFragment& m : e.missed) {
    int k = std::snprintf(b, sizeof b, "lane %d fillet %d: %.1f mm %s", m.lane, m.fillet, m.size_mm,
                          m.shape.c_str());
    if (m.volume_mm3 > 0)  // the bone it holds, as the sphere of its volume
      k += std::snprintf(b + k, sizeof b - size_t(k), " (the volume of a %.1f mm sphere)",
                         std::cbrt(6 * m.volume_mm3 / M_PI));
    k += std::snprintf(b + k, sizeof b - size_t(k), ", calcification %.2f", m.calcification);
    // The edge is looked for within 5 mm (EdgeMap::distance_mm).
    char edge[16] = ">= 5";
    if (m.edge_mm < 5) std::snprintf(edge, sizeof edge, "%.1f", m.edge_mm);
    if (m.meat_mm >= 0)
      k += std::snprintf(b + k, sizeof b - size_t(k),
                         ", under %.1f mm of meat, %s mm from the edge", m.meat_mm, edge);
    // Whether the bone went down the line all the same.
    const char* fate = m.fillet_decision == "not_inspected"
                           ? "; its fillet not inspected (rejected by the fail-safe)"
                       : m.fillet_decision == "reject"
                           ? "; its fillet rejected for another detection"
                           : "";
    out += std::string(b) + margin_text(m) + chance_text(m) + fate + "\n";
  }
  return out;
}

std::string missed_summary(const DetectionEval& e) {
  int n[4] = {0, 0, 0, 0};
  for (const MissedFragment& m : e.missed) ++n[miss_place(m)];
  char b[160];
  if (n[kUnknown]) {
    std::snprintf(b, sizeof b, "%d missed", n[kUnknown]);
    return b;
  }
  std::snprintf(b, sizeof b, "%d under >= 25 mm of meat, %d at the edge, %d elsewhere", n[kThick],
                n[kEdge], n[kElsewhere]);
  return b;
}

std::string detection_table(const DetectionEval& a, const DetectionEval& b, int bits) {
  static const char* kSizes[kSizeBins] = {"1-2 mm", "2-3 mm", "3-5 mm", "5-10 mm"};
  static const char* kCalc[kCalcBins] = {"weakly calcified", "calcified"};
  std::ostringstream os;
  char buf[256];
  auto pct = [](int f, int t) { return t ? 100.0 * f / t : 0.0; };
  os << "bone fragment recall (found by the detector / present)\n";
  std::snprintf(buf, sizeof buf, "%-8s %-17s %20s %20s\n", "size", "calcification", "rangex",
                "X-ray only");
  os << buf;
  for (int s = 0; s < kSizeBins; ++s)
    for (int c = kCalcBins - 1; c >= 0; --c) {
      std::snprintf(buf, sizeof buf, "%-8s %-17s %8d/%-4d %6.1f%% %8d/%-4d %6.1f%%\n", kSizes[s],
                    kCalc[c], a.found[s][c], a.total[s][c], pct(a.found[s][c], a.total[s][c]),
                    b.found[s][c], b.total[s][c], pct(b.found[s][c], b.total[s][c]));
      os << buf;
    }
  const double range = double((1 << bits) - 1);
  auto row = [&](const char* name, const char* fmt, double x, double y) {
    char v1[64], v2[64];
    std::snprintf(v1, sizeof v1, fmt, x);
    std::snprintf(v2, sizeof v2, fmt, y);
    std::snprintf(buf, sizeof buf, "%-44s %14s %18s\n", name, v1, v2);
    os << buf;
  };
  os << "\n";
  row("recall, calcified fragments >= 2 mm", "%.2f%%", 100 * a.recall_calcified_2mm(),
      100 * b.recall_calcified_2mm());
  row("false rejects of clean fillets", "%.2f%%", 100 * a.false_reject_rate(),
      100 * b.false_reject_rate());
  row("  of which not inspected (fail-safe)", "%.0f", a.clean_not_inspected, b.clean_not_inspected);
  row("fillets with bone rejected", "%.2f%%",
      a.bony_fillets ? 100.0 * a.bony_rejected / a.bony_fillets : 0,
      b.bony_fillets ? 100.0 * b.bony_rejected / b.bony_fillets : 0);
  row("fillets with calcified >= 2 mm passed", "%.0f", a.calcified_passed, b.calcified_passed);
  row("detections matching no bone", "%.0f", a.false_fragments, b.false_fragments);
  row("fragment position error, mean (mm)", "%.3f", a.position.stats().mean_abs,
      b.position.stats().mean_abs);
  row("residual I - P: mean (DN)", "%.2f", a.resid_mean_dn, b.resid_mean_dn);
  row("residual I - P: std (DN)", "%.2f", a.resid_std_dn, b.resid_std_dn);
  row("residual std, % of the 12-bit range", "%.3f%%", 100 * a.resid_std_dn / range,
      100 * b.resid_std_dn / range);
  std::snprintf(buf, sizeof buf,
                "fillets: %d inspected, %d not inspected (fail-safe); true fillets %d clean, %d "
                "with bone, %d never seen\n",
                a.fillets - a.not_inspected, a.not_inspected, a.clean_fillets, a.bony_fillets,
                a.unmatched_truth_fillets);
  os << buf
     << "dissertation (real fillets): residual mean 23.7 DN, std 29.6 DN, 1.5% of the range\n";
  if (!a.missed.empty()) os << "\nmissed calcified fragments >= 2 mm:\n" << missed_lines(a);
  return os.str();
}

std::string detection_json(const DetectionEval& a, const DetectionEval& b, int bits) {
  std::ostringstream os;
  auto one = [&](const DetectionEval& e) {
    os << "{\"recall_calcified_ge_2mm\": " << e.recall_calcified_2mm()
       << ", \"false_reject_rate\": " << e.false_reject_rate()
       << ", \"clean_fillets\": " << e.clean_fillets << ", \"clean_rejected\": " << e.clean_rejected
       << ", \"not_inspected\": " << e.not_inspected
       << ", \"false_fragments\": " << e.false_fragments
       << ", \"calcified_fillets\": " << e.calcified_fillets
       << ", \"calcified_fillets_passed\": " << e.calcified_passed
       << ", \"position_error_mm\": " << e.position.stats().mean_abs
       << ", \"residual_mean_dn\": " << e.resid_mean_dn
       << ", \"residual_std_dn\": " << e.resid_std_dn
       << ", \"residual_std_pct\": " << 100 * e.resid_std_dn / double((1 << bits) - 1)
       << ", \"recall\": [";
    for (int s = 0; s < kSizeBins; ++s)
      for (int c = 0; c < kCalcBins; ++c)
        os << (s || c ? ", " : "") << "{\"size_bin\": " << s << ", \"calcified\": " << c
           << ", \"found\": " << e.found[s][c] << ", \"total\": " << e.total[s][c] << "}";
    os << "]}";
  };
  os << "{\"rangex\": ";
  one(a);
  os << ", \"xray_only\": ";
  one(b);
  os << "}";
  return os.str();
}

}  // namespace rangex
