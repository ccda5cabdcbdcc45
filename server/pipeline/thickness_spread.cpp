#include "pipeline/thickness_spread.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/robust_fit.h"

namespace rangex {

namespace {

// Linear between bin centres, constant beyond the first and last.
double interpolate(const std::vector<double>& x, const std::vector<double>& y, double t) {
  if (x.size() == 1 || t <= x.front()) return y.front();
  if (t >= x.back()) return y.back();
  const size_t k = size_t(std::upper_bound(x.begin(), x.end(), t) - x.begin());
  const double w = (x[k] - x[k - 1]) > 0 ? (t - x[k - 1]) / (x[k] - x[k - 1]) : 0.0;
  return y[k - 1] + w * (y[k] - y[k - 1]);
}
}  // namespace

ThicknessBins thickness_bins(const float* thickness, const uint8_t* use, size_t n, int max_bins,
                             size_t min_per_bin) {
  std::vector<size_t> usable;
  for (size_t i = 0; i < n; ++i)
    if (use[i] && std::isfinite(thickness[i])) usable.push_back(i);
  // One bin (one spread per fillet, the default; or a small fillet): no order is needed, only
  // the median thickness, the same rank of the same values as the sorted order below gives.
  // Its members stay in image order, so that each statistic's values are read in order.
  if (max_bins <= 1 || usable.size() / std::max<size_t>(1, min_per_bin) < 2) {
    ThicknessBins b;
    if (usable.empty()) return b;
    std::vector<float> t(usable.size());
    for (size_t k = 0; k < usable.size(); ++k) t[k] = thickness[usable[k]];
    const auto mid = t.begin() + long(t.size() / 2);
    std::nth_element(t.begin(), mid, t.end());
    b.centre_mm.push_back(*mid);
    b.members.push_back(std::move(usable));
    return b;
  }
  // Sorted as (thickness, index) pairs by thickness alone: the same comparisons, so the same
  // order, ties included, as sorting the indices through the image, without a scattered read
  // per comparison. Indices in 32 bits where they fit (every fillet): half the memory moved.
  std::vector<size_t> px;
  auto sort_by = [&]<class Index>(Index) {
    struct At {
      float t;
      Index i;
    };
    std::vector<At> by_t;
    by_t.reserve(usable.size());
    for (size_t i : usable) by_t.push_back({thickness[i], Index(i)});
    std::sort(by_t.begin(), by_t.end(), [](const At& a, const At& b) { return a.t < b.t; });
    px.resize(by_t.size());
    for (size_t k = 0; k < by_t.size(); ++k) px[k] = by_t[k].i;
  };
  if (n <= std::numeric_limits<uint32_t>::max())
    sort_by(uint32_t{});
  else
    sort_by(size_t{});
  ThicknessBins b;
  if (px.empty()) return b;
  const size_t bins = std::clamp<size_t>(px.size() / std::max<size_t>(1, min_per_bin), 1,
                                         size_t(std::max(1, max_bins)));
  for (size_t k = 0; k < bins; ++k) {
    const size_t lo = px.size() * k / bins, hi = px.size() * (k + 1) / bins;
    b.members.emplace_back(px.begin() + long(lo), px.begin() + long(hi));
    b.centre_mm.push_back(thickness[px[(lo + hi) / 2]]);
  }
  return b;
}

double SpreadProfile::median_at(double t) const {
  return interpolate(centre_mm, median, t);
}
double SpreadProfile::scale_at(double t) const {
  return interpolate(centre_mm, scale, t);
}

SpreadProfile spread_profile(const std::vector<float>& v, const ThicknessBins& bins, double floor) {
  SpreadProfile s;
  // The median over the floats themselves, the deviations from it in double (exact).
  std::vector<float> vals;
  std::vector<double> tmp;
  for (size_t k = 0; k < bins.members.size(); ++k) {
    vals.clear();
    for (size_t i : bins.members[k])
      if (std::isfinite(v[i])) vals.push_back(v[i]);
    if (vals.empty()) continue;
    const double med = median_inplace(vals.data(), vals.size());
    tmp.resize(vals.size());
    for (size_t j = 0; j < vals.size(); ++j) tmp[j] = std::abs(double(vals[j]) - med);
    const double sd = median_inplace(tmp.data(), tmp.size()) / kMadNormal;
    s.centre_mm.push_back(bins.centre_mm[k]);
    s.median.push_back(med);
    s.scale.push_back(std::max(sd, floor));
  }
  return s;
}

SpreadProfile unit_spread_by_thickness(std::vector<float>& v, const float* thickness,
                                       const uint8_t* use, const ThicknessBins& bins,
                                       double floor) {
  SpreadProfile s = spread_profile(v, bins, floor);
  if (s.centre_mm.empty()) return s;
  for (size_t i = 0; i < v.size(); ++i) {
    if (!use[i] || !std::isfinite(v[i])) continue;
    const double t = std::isfinite(thickness[i]) ? thickness[i] : s.centre_mm.front();
    v[i] = float((v[i] - s.median_at(t)) / s.scale_at(t));
  }
  return s;
}

}  // namespace rangex
