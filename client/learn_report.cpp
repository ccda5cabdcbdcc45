#include "learn_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "calib/report_plots.h"
#include "core/error.h"

namespace rangex::cli {

namespace {

// A band's middle for plots (the open last band: 5 mm into it).
double band_mid(const std::vector<double>& e, size_t b) {
  return e[b + 1] - e[b] > 50 ? e[b] + 5 : 0.5 * (e[b] + e[b + 1]);
}

}  // namespace

void write_learn_plots(const std::filesystem::path& dir, int lane, const ProductLearning& L,
                       const SensitivityResult& s) {
  const auto& e = L.learned.band_edges_mm;
  const std::string stem = (dir / ("lane" + std::to_string(lane))).string();
  // Thresholds against thickness: round red, needle green, air blue.
  std::vector<Series> th;
  const unsigned char col[3][3] = {{200, 30, 30}, {30, 150, 30}, {30, 60, 200}};
  double ymax = 6;
  for (int k = 0; k < kStatistics; ++k) {
    Series ser;
    ser.r = col[k][0], ser.g = col[k][1], ser.b = col[k][2];
    const auto& t = L.learned.stats[size_t(k)].thresholds;
    for (size_t b = 0; b < t.size(); ++b)
      for (double dx = -1; dx <= 1; dx += 0.25)  // a short bar per band
        ser.x.push_back(band_mid(e, b) + dx), ser.y.push_back(t[b]), ymax = std::max(ymax, t[b]);
    th.push_back(ser);
  }
  plot_points(stem + "_thresholds.png", th, 0, band_mid(e, e.size() - 2) + 5, 0, ymax * 1.15, 5, 1);
  // Sensitivity: the claimed size at 95 % per band, spheres red, needles blue.
  std::vector<Series> se(2);
  se[1].r = 30, se[1].g = 60, se[1].b = 200;
  for (const SensitivityClaim& c : s.claims)
    for (double dx = -1; dx <= 1; dx += 0.25)
      se[size_t(c.shape)].x.push_back(band_mid(e, size_t(c.band)) + dx),
          se[size_t(c.shape)].y.push_back(c.size_mm);
  if (s.inspections > 0)  // not measured: no plot that reads as "found nothing"
    plot_points(stem + "_sensitivity.png", se, 0, band_mid(e, e.size() - 2) + 5, 0, 6, 5, 1);
  // QQ: observed against expected Gumbel variates; the diagonal in grey.
  std::vector<Series> qq;
  Series diag;
  diag.r = diag.g = diag.b = 150;
  for (double v = -2; v <= 8; v += 0.05) diag.x.push_back(v), diag.y.push_back(v);
  qq.push_back(diag);
  for (int k = 0; k < kStatistics; ++k) {
    Series ser;
    ser.r = col[k][0], ser.g = col[k][1], ser.b = col[k][2];
    for (const QQPoint& q : L.stats[size_t(k)].qq)
      ser.x.push_back(q.expected), ser.y.push_back(std::clamp(q.observed, -2.0, 8.0));
    qq.push_back(ser);
  }
  plot_points(stem + "_qq.png", qq, -2, 8, -2, 8, 1, 1, 400, 400);
}

std::string learn_summary_text(int lane, const ProductLearning& L, const SensitivityResult& s) {
  std::ostringstream o;
  char b[256];
  std::snprintf(
      b, sizeof b,
      "lane %d: %s, %d clean fillets, target %.2f %% false rejects at %.0f %% confidence\n", lane,
      L.ok ? "learned" : "FAILED", L.fillets, 100 * L.learned.target_frr,
      100 * L.learned.confidence);
  o << b;
  for (const std::string& p : L.problems) o << "  problem: " << p << "\n";
  for (const FlaggedFillet& f : L.kept) {
    std::snprintf(b, sizeof b,
                  "  kept, checked clean: lane %d fillet %lld (belt %.0f mm), %s extreme %.1f in "
                  "band %d: the thresholds rise over it\n",
                  f.lane, (long long)f.id, f.y0_mm, statistic_name(f.stat), f.x, f.band);
    o << b;
  }
  const auto& e = L.learned.band_edges_mm;
  o << "  thickness band (mm):";
  for (size_t k = 0; k + 1 < e.size(); ++k) {
    std::snprintf(
        b, sizeof b, " %5s",
        (std::to_string(int(e[k])) + (e[k + 1] > 100 ? "+" : "-" + std::to_string(int(e[k + 1]))))
            .c_str());
    o << b;
  }
  o << "\n";
  for (int k = 0; k < kStatistics; ++k) {
    const StatisticLearning& st = L.stats[size_t(k)];
    std::snprintf(b, sizeof b, "  %-6s thresholds:  ", statistic_name(k));
    o << b;
    for (double t : L.learned.stats[size_t(k)].thresholds) {
      std::snprintf(b, sizeof b, " %5.2f", t);
      o << b;
    }
    std::snprintf(b, sizeof b, "   (xi %.2f, implied %.3f %% of fillets, KS p %.2f)\n",
                  st.fit.model.xi, 100 * st.implied_frr, st.ks_p);
    o << b;
    if (st.fit.tail_from > 0) {
      std::snprintf(b, sizeof b,
                    "         its top: %d of %d extremes above the whole fit's 99 %% (%.1f "
                    "expected, chance %.3f): fitted to the tail above the whole fit's %.0f %%\n",
                    st.top_above, st.samples, kTopShare * st.samples, st.top_p,
                    100 * st.fit.tail_from);
      o << b;
    }
  }
  // What the confidence costs: the thresholds spend only part of the budget by the fitted
  // models, and a longer learning run (a narrower margin) spends more of it.
  const double implied = implied_false_reject_rate(L.learned);
  std::snprintf(b, sizeof b, "  together: implied %.3f %% of fillets, of the %.2f %% asked",
                100 * implied, 100 * L.learned.target_frr);
  o << b;
  if (L.ok && implied < 0.5 * L.learned.target_frr) {
    std::snprintf(b, sizeof b,
                  ": the rest is the margin for %.0f %% confidence from %d fillets; a longer "
                  "learning run narrows it",
                  100 * L.learned.confidence, L.fillets);
    o << b;
  }
  o << "\n";
  for (const std::string& line : s.summary) o << "  sensitivity: " << line << "\n";
  return o.str();
}

// --keep 0:25,1:3: fillets a failed learning named that an operator checked and found
// clean (lane:fillet, as the learning names them).
std::vector<std::pair<int, int64_t>> checked_clean_fillets(const std::string& v) {
  std::vector<std::pair<int, int64_t>> out;
  std::stringstream list(v);
  std::string item;
  while (std::getline(list, item, ',')) {
    const size_t colon = item.find(':');
    char* end = nullptr;
    const long lane = colon == std::string::npos ? -1 : std::strtol(item.c_str(), &end, 10);
    const bool lane_ok = colon != std::string::npos && end == item.c_str() + colon && lane >= 0;
    const long long id = lane_ok ? std::strtoll(item.c_str() + colon + 1, &end, 10) : -1;
    if (!lane_ok || item.size() == colon + 1 || *end != '\0' || id < 0 || lane > 1000)
      fail("--keep: expected LANE:FILLET (e.g. 0:25), got '", item, "'");
    out.push_back({int(lane), int64_t(id)});
  }
  if (out.empty()) fail("--keep: expected LANE:FILLET,... (e.g. 0:25)");
  return out;
}

// --tradeoff 0.001,0.01: false-reject targets beside the lane's, each a fraction in (0, 0.5).
std::vector<double> tradeoff_targets(const std::string& v) {
  std::vector<double> out;
  std::stringstream list(v);
  std::string item;
  while (std::getline(list, item, ',')) {
    char* end = nullptr;
    const double t = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !(t > 0 && t < 0.5))
      fail(
          "--tradeoff: expected false-reject targets in (0, 0.5) separated by commas (e.g. "
          "0.001,0.01), got '",
          item, "'");
    out.push_back(t);
  }
  if (out.empty() || out.size() > 8) fail("--tradeoff: 1 to 8 targets (e.g. 0.001,0.01)");
  return out;
}

namespace {

// "round thresholds 6.1-12.0": a statistic's lowest and highest over the bands.
std::string threshold_range(const LearnedDetection& L, int stat) {
  const auto& t = L.stats[size_t(stat)].thresholds;
  if (t.empty()) return "-";
  char b[48];
  std::snprintf(b, sizeof b, "%.1f-%.1f", *std::min_element(t.begin(), t.end()),
                *std::max_element(t.begin(), t.end()));
  return b;
}

// The sphere claimed at 95 % in each band ("1.5 1.5 2.0 2.5 3.0 - - -"; "-": none).
std::string spheres_by_band(const SensitivityResult& s) {
  const int bands = std::max(0, int(s.band_edges_mm.size()) - 1);
  std::string out;
  for (int b = 0; b < bands; ++b) {
    char v[16] = "-";
    for (const SensitivityClaim& c : s.claims)
      if (c.shape == TestPiece::kSphere && c.band == b)
        std::snprintf(v, sizeof v, "%.1f", c.size_mm);
    out.append(b ? " " : "").append(v);
  }
  return out;
}

}  // namespace

// The learned target and each other one, a line each: what it implies, its thresholds and
// what they buy.
std::string tradeoff_text(const LaneLearning& l, const std::vector<TradeoffPoint>& points) {
  struct Row {
    double target, implied;
    const LearnedDetection* learned;
    const SensitivityResult* sensitivity;
  };
  std::vector<Row> rows;
  const LearnedDetection& L = l.learning.learned;
  rows.push_back({L.target_frr, implied_false_reject_rate(L), &L, &l.sensitivity});
  for (const TradeoffPoint& t : points)
    rows.push_back({t.target_frr, t.implied_frr, &t.learned, &t.sensitivity});
  std::sort(rows.begin(), rows.end(),
            [](const Row& a, const Row& b) { return a.target < b.target; });
  std::string out =
      "  what each false-reject target buys (the same fillets and test pieces; the sphere "
      "claimed at 95 % by band, mm):\n";
  for (const Row& r : rows) {
    char b[160];
    std::snprintf(
        b, sizeof b, "    %5.2f %% (implied %.3f %%; round %s, needle %s)%s: ", 100 * r.target,
        100 * r.implied, threshold_range(*r.learned, kStatRound).c_str(),
        threshold_range(*r.learned, kStatNeedle).c_str(), r.learned == &L ? ", learned" : "");
    std::string line = b + spheres_by_band(*r.sensitivity);
    for (const std::string& k : r.sensitivity->summary) line += "\n      " + k;
    out += line + "\n";
  }
  return out;
}

}  // namespace rangex::cli
