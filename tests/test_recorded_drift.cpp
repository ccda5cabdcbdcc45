// The drift monitor run over inspected records (offline/recorded_drift.h), as rangexctl
// process and eval-matrix run it: band extremes drawn from a known extreme-value model, a
// product learned from 40 fillets of it, then runs of records written to CSV and read back
// (offline/fillet_records.h). Over 300 more fillets of the same product it stays quiet; when
// later runs' tail grows (the same location, twice the scale: specks the median does not
// see) it warns, and only in them.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/error.h"
#include "offline/fillet_records.h"
#include "offline/recorded_drift.h"
#include "pipeline/product_learning.h"
#include "temp_dir.h"

namespace rangex {
namespace {

// The product's per-band extremes: three thickness bands of 2,000 pixels, every statistic.
std::vector<BandExtreme> draw_extremes(std::mt19937_64& rng, double scale_factor) {
  GevModel g;
  g.m0 = 4.0, g.m_t = 0.03, g.s0 = std::log(0.45 * scale_factor), g.xi = 0.02;
  g.log_n_ref = std::log(2000.0), g.t_ref = 12.5;
  std::uniform_real_distribution<double> u(1e-9, 1 - 1e-9);
  std::vector<BandExtreme> out;
  for (int s = 0; s < kStatistics; ++s)
    for (int b = 1; b <= 3; ++b) {
      const double t = 5.0 * b + 2.5;
      out.push_back({s, b, (s == kStatAir ? 20.0 : 1.0) * g.quantile(u(rng), 2000, t), 2000, t});
    }
  return out;
}

// `fillets` fillets of lane `lane` inspected with `L`: passed unless a rejecting statistic's
// extreme reaches its band's threshold; every fillet's extremes recorded.
RecordSet inspected_run(std::mt19937_64& rng, const LearnedDetection& L, int fillets,
                        double scale_factor, int64_t first_id, int lane = 0) {
  RecordSet run;
  for (int i = 0; i < fillets; ++i) {
    const auto ex = draw_extremes(rng, scale_factor);
    bool reject = false;
    for (const BandExtreme& e : ex)
      reject |= e.stat != kStatAir && e.x >= L.stats[size_t(e.stat)].thresholds[size_t(e.band)];
    FilletRecord f;
    f.lane = lane, f.fillet = first_id + i, f.decision = reject ? "reject" : "pass";
    run.fillets.push_back(f);
    for (const BandExtreme& e : ex) run.extremes.push_back({lane, f.fillet, e});
  }
  return run;
}

LearnedDetection learned_product() {
  std::mt19937_64 rng(7);
  std::vector<LearningFillet> learn;
  for (int i = 0; i < 40; ++i) learn.push_back({0, i, 0.0, draw_extremes(rng, 1.0)});
  LearnOptions o;
  o.bootstrap = 40;
  ProductLearning P = learn_product(learn, o);
  EXPECT_TRUE(P.ok) << (P.problems.empty() ? "" : P.problems[0]);
  P.learned.version = "test";
  return P.learned;
}

TEST(RecordedDrift, QuietOnTheLearnedProductWarnsOnlyOnceItsTailGrows) {
  const LearnedDetection L = learned_product();
  ASSERT_TRUE(L.active());
  test::TempDir tmp;
  std::mt19937_64 rng(11);
  std::vector<RecordSet> runs;
  for (int k = 0; k < 3; ++k) {
    // Through the CSV files, as eval-matrix reads process's output back.
    const RecordSet written = inspected_run(rng, L, 100, 1.0, 100 * k);
    const std::string dir = tmp.str("run" + std::to_string(k));
    write_records(dir, "", written);
    runs.push_back(read_records(dir, ""));
    ASSERT_EQ(runs.back().extremes.size(), written.extremes.size());
    for (size_t i = 0; i < written.extremes.size(); ++i) {
      EXPECT_EQ(runs.back().extremes[i].fillet, written.extremes[i].fillet);
      EXPECT_EQ(runs.back().extremes[i].extreme.stat, written.extremes[i].extreme.stat);
      EXPECT_EQ(runs.back().extremes[i].extreme.band, written.extremes[i].extreme.band);
      EXPECT_NEAR(runs.back().extremes[i].extreme.x, written.extremes[i].extreme.x,
                  1e-5 * std::abs(written.extremes[i].extreme.x));
    }
  }
  // Another lane's fillets in the same records are not this lane's product.
  runs.back() = [&] {
    RecordSet r = runs.back();
    const RecordSet other = inspected_run(rng, L, 50, 3.0, 0, 1);
    r.fillets.insert(r.fillets.end(), other.fillets.begin(), other.fillets.end());
    r.extremes.insert(r.extremes.end(), other.extremes.begin(), other.extremes.end());
    return r;
  }();
  const RecordedDrift same = recorded_drift(L, runs, 0);
  EXPECT_GE(same.passed, 290);
  EXPECT_LE(same.passed, 300);
  EXPECT_EQ(same.last.fillets, 200);
  EXPECT_FALSE(same.drifting) << same.last.implied_frr;
  EXPECT_EQ(same.first_flagged, -1) << same.highest_frr;
  EXPECT_LT(same.highest_frr, 2 * L.target_frr);
  EXPECT_GT(same.learned_frr, 0);
  const std::string quiet = drift_sentence(0, same);
  EXPECT_NE(quiet.find("the last 200 of"), std::string::npos) << quiet;
  EXPECT_EQ(quiet.find("rougher than learned"), std::string::npos) << quiet;

  for (int k = 3; k < 6; ++k) runs.push_back(inspected_run(rng, L, 100, 2.0, 100 * k));
  const RecordedDrift rougher = recorded_drift(L, runs, 0);
  EXPECT_TRUE(rougher.drifting) << rougher.last.implied_frr;
  EXPECT_GT(rougher.first_flagged, same.passed);
  EXPECT_GT(rougher.last.implied_frr, 2 * L.target_frr);
  EXPECT_GE(rougher.highest_frr, rougher.last.implied_frr);
  const std::string warned = drift_sentence(0, rougher);
  EXPECT_NE(warned.find("lane 0: product rougher than learned: re-learn"), std::string::npos)
      << warned;
  EXPECT_NE(warned.find("it warned first at passed fillet"), std::string::npos) << warned;
}

TEST(RecordedDrift, TooFewPassedFilletsSayNothingAndNoLearningIsAnError) {
  const LearnedDetection L = learned_product();
  std::mt19937_64 rng(3);
  const RecordedDrift d = recorded_drift(L, {inspected_run(rng, L, 30, 1.0, 0)}, 0);
  EXPECT_FALSE(d.drifting);
  EXPECT_EQ(d.first_flagged, -1);
  EXPECT_NE(drift_sentence(0, d).find("fewer than the 200 it needs"), std::string::npos);
  EXPECT_EQ(d.last.implied_frr, -1);  // not estimated, as a live lane shows it
  EXPECT_NE(drift_json(d).find("\"implied_frr\": -1,"), std::string::npos) << drift_json(d);
  EXPECT_THROW(recorded_drift(LearnedDetection{}, {}, 0), Error);
}

}  // namespace
}  // namespace rangex
