#include "pipeline/product_learning.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "pipeline/binomial_tail.h"
#include "pipeline/robust_fit.h"

namespace rangex {

namespace {

bool rejecting(int s) {
  return s != kStatAir;
}

double median_of(std::vector<double> v) {
  return v.empty() ? 0.0 : median_inplace(v.data(), v.size());
}

// Where each band sits among the learning fillets: how often it is present, with how many
// pixels and what thickness (medians over the fillets that hold it).
struct BandUse {
  std::vector<double> fraction, pixels, thickness;
};

BandUse band_use(const std::vector<const LearningFillet*>& fillets, int stat, int bands) {
  BandUse u;
  for (int b = 0; b < bands; ++b) {
    std::vector<double> n, t;
    for (const LearningFillet* f : fillets)
      for (const BandExtreme& e : f->extremes)
        if (e.stat == stat && e.band == b) n.push_back(e.n), t.push_back(e.t);
    u.fraction.push_back(fillets.empty() ? 0.0 : double(n.size()) / double(fillets.size()));
    u.pixels.push_back(median_of(n));
    u.thickness.push_back(median_of(t));
  }
  return u;
}

std::vector<ExtremeSample> samples_of(const std::vector<const LearningFillet*>& fillets, int stat) {
  std::vector<ExtremeSample> s;
  for (const LearningFillet* f : fillets)
    for (const BandExtreme& e : f->extremes)
      if (e.stat == stat) s.push_back({e.x, e.n, e.t});
  return s;
}

// Per band the quantile that spends `budget` over the bands in proportion to their expected
// pixels (a pixel anywhere is as likely to raise a false detection); absent bands take
// their nearest present neighbour's threshold.
std::vector<double> thresholds_for(const GevModel& g, const BandUse& u, double budget) {
  const size_t bands = u.fraction.size();
  double w = 0;
  for (size_t b = 0; b < bands; ++b) w += u.fraction[b] * u.pixels[b];
  std::vector<double> t(bands, NAN);
  for (size_t b = 0; b < bands; ++b) {
    if (u.fraction[b] <= 0 || w <= 0) continue;
    const double q = std::clamp(budget * u.pixels[b] / w, 1e-12, 0.5);
    t[b] = std::max(1.0, g.quantile(1 - q, u.pixels[b], u.thickness[b]));
  }
  for (size_t b = 0; b < bands; ++b) {
    if (std::isfinite(t[b])) continue;
    for (size_t d = 1; d < bands && !std::isfinite(t[b]); ++d) {
      if (b >= d && std::isfinite(t[b - d]) && u.fraction[b - d] > 0)
        t[b] = t[b - d];
      else if (b + d < bands && std::isfinite(t[b + d]) && u.fraction[b + d] > 0)
        t[b] = t[b + d];
    }
    if (!std::isfinite(t[b])) t[b] = 5.0;  // no band present at all: the fixed default
  }
  return t;
}

// The per-fillet rate at which `g`'s extremes exceed the thresholds `t` in some band.
double implied(const GevModel& g, const BandUse& u, const std::vector<double>& t) {
  double frr = 0;
  for (size_t b = 0; b < t.size(); ++b)
    if (u.fraction[b] > 0)
      frr += u.fraction[b] * std::exp(g.log_survival(t[b], u.pixels[b], u.thickness[b]));
  return frr;
}

// Kolmogorov's asymptotic p-value for D over n samples.
double ks_pvalue(double d, size_t n) {
  const double sn = std::sqrt(double(n)), l = (sn + 0.12 + 0.11 / sn) * d;
  double p = 0;
  for (int k = 1; k <= 100; ++k) p += 2 * ((k & 1) ? 1 : -1) * std::exp(-2.0 * k * k * l * l);
  return std::clamp(p, 0.0, 1.0);
}

// The extremes the model was fitted to against it: every one, or for a tail fit those above
// the level that censored them, each as (F(x) - F(c)) / (1 - F(c)), uniform above c under
// the model.
void qq_and_ks(const GevFit& fit, const std::vector<ExtremeSample>& s, StatisticLearning& out) {
  const GevModel& g = fit.model;
  std::vector<double> u;
  for (const auto& e : s) {
    double lo = 0;
    if (fit.tail_from > 0) {
      const double c = tail_level(fit.whole, fit.tail_from, e.n, e.t);
      if (e.x <= c) continue;
      lo = g.cdf(c, e.n, e.t);
    }
    const double p = (g.cdf(e.x, e.n, e.t) - lo) / std::max(1e-300, 1 - lo);
    u.push_back(std::clamp(p, 1e-300, 1 - 1e-16));
  }
  std::sort(u.begin(), u.end());
  const size_t n = u.size();
  double d = 0;
  for (size_t i = 0; i < n; ++i) {
    d = std::max({d, std::abs(u[i] - double(i) / n), std::abs(u[i] - double(i + 1) / n)});
    const double p = (double(i) + 0.5) / double(n);
    out.qq.push_back({-std::log(-std::log(p)), -std::log(-std::log(u[i]))});
  }
  out.ks_d = d;
  out.ks_p = n ? ks_pvalue(d, n) : 1;
  out.ks_samples = int(n);
}

// How many of the extremes lie above the model's 1 - kTopShare (99 %) quantile at their own
// covariates, and the chance of that many or more if the model holds: a bulk fitted well says
// nothing of a tail that a second population makes (the Kolmogorov-Smirnov test hardly sees the
// top).
void top_check(const GevModel& g, const std::vector<ExtremeSample>& s, StatisticLearning& out) {
  int above = 0;
  for (const auto& e : s) above += g.log_survival(e.x, e.n, e.t) < std::log(kTopShare);
  out.top_above = above;
  out.top_p = above == 0 ? 1.0 : 1 - binomial_at_most(above - 1, int(s.size()), kTopShare);
}

// The most improbable extreme of the rejecting statistics of fillet `f` under models fitted
// without it (only for the few most extreme candidates: each costs a fit per statistic).
FlaggedFillet worst_of(const LearningFillet& f, const std::array<GevModel, kStatistics>& without) {
  FlaggedFillet w{f.lane, f.id, f.y0_mm, 0, 0, 0, 0};
  for (const BandExtreme& e : f.extremes) {
    if (!rejecting(e.stat)) continue;
    const double ls =
        std::max(-300.0, without[size_t(e.stat)].log_survival(e.x, e.n, e.t) / std::log(10.0));
    if (ls < w.log10_survival) w.stat = e.stat, w.band = e.band, w.x = e.x, w.log10_survival = ls;
  }
  return w;
}

// The learning run's fillets that are fit to learn from: those with extremes, less those
// that hold something like bone (in r.flagged; a fillet checked clean stays, in r.kept when
// the model would have named it); what is wrong goes to r.problems.
std::vector<const LearningFillet*> clean_fillets(const std::vector<LearningFillet>& all,
                                                 const LearnOptions& opt, int bands,
                                                 ProductLearning& r) {
  std::vector<const LearningFillet*> use;
  for (const auto& f : all)
    if (!f.extremes.empty()) use.push_back(&f);
  auto checked = [&](const LearningFillet& f) {
    return std::find(opt.checked_clean.begin(), opt.checked_clean.end(),
                     std::pair<int, int64_t>{f.lane, f.id}) != opt.checked_clean.end();
  };
  for (const auto& [lane, id] : opt.checked_clean)
    if (std::none_of(all.begin(), all.end(),
                     [&](const LearningFillet& f) { return f.lane == lane && f.id == id; }))
      r.problems.push_back("lane " + std::to_string(lane) + " fillet " + std::to_string(id) +
                           ", checked clean, is not in the learning run");
  auto fit_stat = [&](const std::vector<const LearningFillet*>& fs, int s) -> GevFit {
    const auto smp = samples_of(fs, s);
    if (smp.size() < 10) return {};
    return fit_gev(smp);
  };
  // Bone in the learning run, in two steps. First a gross-error screen that several bony
  // fillets cannot mask: per statistic and band, a fillet whose extreme stands more than
  // `gross_mads` robust deviations (median and MAD across the fillets) above the others'.
  // Then, one at a time, the fillets that stand out most, each judged by the model fitted
  // without it.
  {
    std::vector<const LearningFillet*> rest;
    std::map<std::pair<int, int>, std::pair<double, double>> centre;  // (stat, band): median, sd
    for (int s = 0; s < kStatistics; ++s) {
      if (!rejecting(s)) continue;
      for (int b = 0; b < bands; ++b) {
        std::vector<double> xs;
        for (const LearningFillet* f : use)
          for (const BandExtreme& e : f->extremes)
            if (e.stat == s && e.band == b) xs.push_back(e.x);
        if (xs.size() < 5) continue;
        const double med = median_of(xs);
        for (double& x : xs) x = std::abs(x - med);
        centre[{s, b}] = {med, std::max(0.1, median_of(xs) / kMadNormal)};
      }
    }
    for (const LearningFillet* f : use) {
      FlaggedFillet worst{f->lane, f->id, f->y0_mm, 0, 0, 0, 0};
      double worst_z = 0;
      for (const BandExtreme& e : f->extremes) {
        const auto it = centre.find({e.stat, e.band});
        if (it == centre.end()) continue;
        const double z = (e.x - it->second.first) / it->second.second;
        if (z > worst_z) worst_z = z, worst.stat = e.stat, worst.band = e.band, worst.x = e.x;
      }
      const bool stands_out = worst_z > opt.gross_mads;
      if (stands_out) {
        worst.robust_z = worst_z;
        (checked(*f) ? r.kept : r.flagged).push_back(worst);
      }
      if (!stands_out || checked(*f)) rest.push_back(f);
    }
    use = rest;
  }
  // Bonferroni over every band extreme of the rejecting statistics that could have stood out.
  auto outlier_limit = [&] {
    size_t tested = 0;
    for (const LearningFillet* f : use)
      for (const BandExtreme& e : f->extremes) tested += rejecting(e.stat);
    return std::log10(opt.outlier_alpha / double(std::max<size_t>(1, tested)));
  };
  // use[i] judged by the model fitted without it; `rest` gets the others.
  auto judged_without = [&](size_t i, std::vector<const LearningFillet*>& rest) {
    rest.clear();
    for (size_t j = 0; j < use.size(); ++j)
      if (j != i) rest.push_back(use[j]);
    std::array<GevModel, kStatistics> without;
    for (int s = 0; s < kStatistics; ++s)
      if (rejecting(s)) without[size_t(s)] = fit_stat(rest, s).model;
    return worst_of(*use[i], without);
  };
  for (int round = 0; round < 8 && int(use.size()) >= 10; ++round) {
    std::array<GevModel, kStatistics> model;
    for (int s = 0; s < kStatistics; ++s)
      if (rejecting(s)) model[size_t(s)] = fit_stat(use, s).model;
    std::vector<std::pair<double, size_t>> order;
    for (size_t i = 0; i < use.size(); ++i)
      if (!checked(*use[i])) order.push_back({worst_of(*use[i], model).log10_survival, i});
    std::sort(order.begin(), order.end());
    const double limit = outlier_limit();
    bool removed = false;
    std::vector<const LearningFillet*> rest;
    for (size_t c = 0; c < std::min<size_t>(3, order.size()) && !removed; ++c) {
      const FlaggedFillet w = judged_without(order[c].second, rest);
      if (w.log10_survival < limit) {
        r.flagged.push_back(w);
        use = rest;
        removed = true;
      }
    }
    if (!removed) break;
  }
  // The checked fillets the model would have named: kept, and said so.
  if (!opt.checked_clean.empty() && int(use.size()) >= 10) {
    const double limit = outlier_limit();
    std::vector<const LearningFillet*> rest;
    for (size_t i = 0; i < use.size(); ++i) {
      const bool said = std::any_of(r.kept.begin(), r.kept.end(), [&](const FlaggedFillet& k) {
        return k.lane == use[i]->lane && k.id == use[i]->id;
      });
      if (!checked(*use[i]) || said) continue;
      const FlaggedFillet w = judged_without(i, rest);
      if (w.log10_survival < limit) r.kept.push_back(w);
    }
  }
  return use;
}

// One statistic's learning over the clean fillets `use`: its extreme-value model (with a tail
// of its own when the bulk's model leaves too many extremes above its top), the thresholds
// that spend its share of the false-reject budget, the bootstrap's `confidence` over them, and
// the checks of the model against the extremes it was fitted to (QQ, Kolmogorov-Smirnov).
void learn_statistic(int s, const std::vector<const LearningFillet*>& use, int bands,
                     bool has_needle, const LearnOptions& opt, std::mt19937_64& rng,
                     StatisticLearning& st, LearnedStatistic& ls,
                     std::vector<std::string>& problems) {
  st.budget = !rejecting(s) ? opt.target_frr : has_needle ? opt.target_frr / 2 : opt.target_frr;
  const auto smp = samples_of(use, s);
  st.samples = int(smp.size());
  const BandUse u = band_use(use, s, bands);
  ls.band_fraction = u.fraction, ls.band_pixels = u.pixels, ls.band_thickness_mm = u.thickness;
  if (smp.size() < 10) {
    if (s == kStatNeedle && !has_needle) {
      ls.thresholds.assign(size_t(bands), 5.0);  // needle kernels off
      return;
    }
    problems.push_back(std::string(statistic_name(s)) + ": only " + std::to_string(smp.size()) +
                       " band extremes to fit");
    ls.thresholds.assign(size_t(bands), 5.0);
    return;
  }
  GevFitOptions fo;
  st.fit = fit_gev(smp, fo);
  if (rejecting(s) && opt.tail_from > 0 && st.fit.converged) {
    top_check(st.fit.model, smp, st);
    if (st.top_p < opt.tail_alpha) {
      fo.tail_from = opt.tail_from;
      st.fit = fit_gev(smp, fo);
      fo.tail_from = st.fit.tail_from;  // 0 if the tail fit did not converge: the bootstrap too
    }
  }
  // Air pockets are reported, never rejected: their fit is information, not a gate.
  if (!st.fit.converged && rejecting(s))
    problems.push_back(std::string(statistic_name(s)) + ": the extreme-value fit did not converge");
  ls.model = st.fit.model;
  ls.tail_from = st.fit.tail_from, ls.whole_model = st.fit.whole;
  st.point_thresholds = thresholds_for(st.fit.model, u, st.budget);
  // The bootstrap over fillets: each resample's model and thresholds; the thresholds used
  // are each band's `confidence` quantile of them.
  std::vector<std::vector<double>> boot(static_cast<size_t>(bands));
  std::uniform_int_distribution<size_t> pick(0, use.size() - 1);
  for (int k = 0; k < opt.bootstrap; ++k) {
    std::vector<const LearningFillet*> re;
    for (size_t i = 0; i < use.size(); ++i) re.push_back(use[pick(rng)]);
    const auto rs = samples_of(re, s);
    if (rs.size() < 10) continue;
    const GevFit f = fit_gev(rs, fo);
    if (!f.converged) continue;
    const auto t = thresholds_for(f.model, band_use(re, s, bands), st.budget);
    for (int b = 0; b < bands; ++b) boot[size_t(b)].push_back(t[size_t(b)]);
  }
  st.thresholds = st.point_thresholds;
  for (int b = 0; b < bands; ++b) {
    auto& v = boot[size_t(b)];
    if (v.size() < 10 || u.fraction[size_t(b)] <= 0) continue;
    std::sort(v.begin(), v.end());
    const double q = v[std::min(v.size() - 1, size_t(opt.confidence * double(v.size())))];
    st.thresholds[size_t(b)] = std::max(st.point_thresholds[size_t(b)], q);
  }
  // A tail too heavy for the extremes it was fitted to (a handful of fillets, xi at its
  // bound) puts thresholds beyond any statistic, and beyond what plant.yaml reads back.
  std::string beyond;
  for (int b = 0; b < bands; ++b) {
    double& t = st.thresholds[size_t(b)];
    if (std::isfinite(t) && t < kMaxLearnedThreshold * 0.999) continue;
    beyond += (beyond.empty() ? "" : ", ") + std::to_string(b);
    t = kMaxLearnedThreshold * 0.999;
  }
  if (!beyond.empty() && rejecting(s)) {
    char m[256];
    std::snprintf(m, sizeof m,
                  "%s: the fitted tail (xi %.2f, from %d extremes) sets no usable threshold in "
                  "band%s %s: learn from more fillets",
                  statistic_name(s), st.fit.model.xi, st.samples,
                  beyond.find(',') == std::string::npos ? "" : "s", beyond.c_str());
    problems.push_back(m);
  }
  ls.thresholds = st.thresholds;
  st.implied_frr = implied(st.fit.model, u, st.thresholds);
  qq_and_ks(st.fit, smp, st);
}

}  // namespace

ProductLearning learn_product(const std::vector<LearningFillet>& all, const LearnOptions& opt) {
  ProductLearning r;
  const int bands = int(opt.band_edges_mm.size()) - 1;
  const std::vector<const LearningFillet*> use = clean_fillets(all, opt, bands, r);
  r.fillets = int(use.size());
  if (r.fillets < opt.min_fillets)
    r.problems.push_back("too few clean fillets: " + std::to_string(r.fillets) + " of the " +
                         std::to_string(opt.min_fillets) + " needed");
  for (const FlaggedFillet& f : r.flagged) {
    char b[256];
    if (f.robust_z > 0)
      std::snprintf(b, sizeof b,
                    "lane %d fillet %lld (belt %.0f mm) holds something like bone: %s extreme "
                    "%.1f in band %d, %.0f robust deviations above the other fillets'",
                    f.lane, (long long)f.id, f.y0_mm, statistic_name(f.stat), f.x, f.band,
                    f.robust_z);
    else
      std::snprintf(b, sizeof b,
                    "lane %d fillet %lld (belt %.0f mm) holds something like bone: %s extreme "
                    "%.1f in band %d, probability 1e%.1f under the others' model",
                    f.lane, (long long)f.id, f.y0_mm, statistic_name(f.stat), f.x, f.band,
                    f.log10_survival);
    r.problems.push_back(b);
  }
  LearnedDetection& L = r.learned;
  L.target_frr = opt.target_frr;
  L.confidence = opt.confidence;
  L.fillets = r.fillets;
  L.band_edges_mm = opt.band_edges_mm;
  L.spread_by_thickness = opt.spread_by_thickness;
  L.rim_walls = opt.rim_walls;
  const bool has_needle = !samples_of(use, kStatNeedle).empty();
  std::mt19937_64 rng(opt.seed);
  for (int s = 0; s < kStatistics; ++s)
    learn_statistic(s, use, bands, has_needle, opt, rng, r.stats[size_t(s)], L.stats[size_t(s)],
                    r.problems);
  r.ok = r.problems.empty();
  return r;
}

double implied_false_reject_rate(const LearnedDetection& L) {
  double frr = 0;
  for (int s = 0; s < kStatistics; ++s) {
    if (!rejecting(s)) continue;
    const LearnedStatistic& ls = L.stats[size_t(s)];
    const size_t bands = ls.thresholds.size();
    if (ls.band_fraction.size() != bands || ls.band_pixels.size() != bands ||
        ls.band_thickness_mm.size() != bands)
      continue;
    const BandUse u{ls.band_fraction, ls.band_pixels, ls.band_thickness_mm};
    frr += implied(ls.model, u, ls.thresholds);
  }
  return std::min(1.0, frr);
}

// The learned model's quantile below which the drift refit leaves an extreme out.
constexpr double kDriftLeftOutBelow = 0.001;

DriftEstimate estimate_drift(const LearnedDetection& L,
                             const std::vector<std::vector<BandExtreme>>& recent) {
  DriftEstimate d;
  d.fillets = int(recent.size());
  for (int s = 0; s < kStatistics; ++s) {
    // Passed fillets: each rejecting statistic's extreme stayed below its band's threshold.
    const LearnedStatistic& ls = L.stats[size_t(s)];
    // Extremes below the learned model's lowest thousandth are left out (the refit is
    // truncated there): a few small bands' extremes deep in the lower tail had widened its
    // scale by a third and implied five times the false rejects of a product that had not
    // changed (a recorded plant's: 0.74 % against 0.15 % learned; 0.21 % without them).
    std::vector<ExtremeSample> smp;
    for (const auto& f : recent)
      for (const BandExtreme& e : f)
        if (e.stat == s)
          smp.push_back({e.x, e.n, e.t,
                         rejecting(s) && size_t(e.band) < ls.thresholds.size()
                             ? ls.thresholds[size_t(e.band)]
                             : HUGE_VAL,
                         ls.model.quantile(kDriftLeftOutBelow, e.n, e.t),
                         // A tail fit is followed where it was fitted: above the same level.
                         tail_level(ls.whole_model, ls.tail_from, e.n, e.t)});
    d.models[size_t(s)] = refit_drifted(ls.model, smp, &d.shift[size_t(s)]);
  }
  LearnedDetection drifted = L;
  for (int s = 0; s < kStatistics; ++s) drifted.stats[size_t(s)].model = d.models[size_t(s)];
  d.implied_frr = implied_false_reject_rate(drifted);
  return d;
}

}  // namespace rangex
