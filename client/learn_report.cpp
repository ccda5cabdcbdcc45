#include "learn_report.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "calib/report_plots.h"

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
  }
  for (const std::string& line : s.summary) o << "  sensitivity: " << line << "\n";
  return o.str();
}

}  // namespace rangex::cli
