#include "pipeline/noise_model.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "pipeline/robust_fit.h"

namespace rangex {

namespace {
// Reorders v[lo, hi) so that each of bins equal-count bins (bin k holds the elements a full
// sort would put at n k / bins .. n (k + 1) / bins) is together, by selection (O(n log bins))
// rather than by sorting: the bins' contents are all that the estimates use.
template <typename T>
void partition_bins(std::vector<T>& v, size_t n, int k0, int k1, int bins) {
  if (k1 - k0 < 2) return;
  const int km = (k0 + k1) / 2;
  const size_t lo = n * k0 / bins, mid = n * km / bins, hi = n * k1 / bins;
  std::nth_element(v.begin() + lo, v.begin() + mid, v.begin() + hi);
  partition_bins(v, n, k0, km, bins);
  partition_bins(v, n, km, k1, bins);
}
}  // namespace

double NoiseModel::sigma_ln(double I) const {
  const double v = a / I + b / (I * I);
  return std::sqrt(std::max(v, 1e-12));
}

double NoiseModel::sigma_ln(double I, double grad2) const {
  const double v = a / I + b / (I * I) + c * grad2;
  return std::sqrt(std::max(v, 1e-12));
}

double estimate_gradient_term(const NoiseModel& m, const float* pred, const float* resid,
                              const float* grad2, size_t n) {
  // Steep ground: where a shift of a third of a pixel would move ln P by more than the
  // photon noise does.
  std::vector<std::pair<float, size_t>> steep;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(pred[i]) || !std::isfinite(resid[i]) || !std::isfinite(grad2[i]) ||
        pred[i] <= 0)
      continue;
    const double v = m.a / pred[i] + m.b / (double(pred[i]) * pred[i]);
    if (grad2[i] / 9.0 > v) steep.emplace_back(grad2[i], i);
  }
  if (steep.size() < 200) return 1.0 / 12;
  const int bins = int(std::clamp<size_t>(steep.size() / 100, 2, 8));
  partition_bins(steep, steep.size(), 0, bins, bins);
  double sgg = 0, sge = 0;
  std::vector<double> tmp;
  for (int k = 0; k < bins; ++k) {
    const size_t lo = steep.size() * k / bins, hi = steep.size() * (k + 1) / bins;
    tmp.clear();
    double g2 = 0, v = 0;
    for (size_t j = lo; j < hi; ++j) {
      const size_t i = steep[j].second;
      tmp.push_back(resid[i]);
      g2 += grad2[i];
      v += m.a / pred[i] + m.b / (double(pred[i]) * pred[i]);
    }
    const double cnt = double(hi - lo);
    g2 /= cnt, v /= cnt;
    const double med = median_inplace(tmp.data(), tmp.size());
    for (double& t : tmp) t = std::abs(t - med);
    const double s = median_inplace(tmp.data(), tmp.size()) / kMadNormal;
    sgg += cnt * g2 * g2;
    sge += cnt * g2 * (s * s - v);
  }
  // Never below what the sampling leaves: the thickness is known at pixel centres, so an
  // edge's place within its pixel is uniform over a pixel (variance 1/12 px^2).
  return std::max(1.0 / 12, sgg > 0 ? sge / sgg : 0.0);
}

NoiseModel estimate_noise_model(const float* pred, const float* resid, size_t n) {
  std::vector<std::pair<float, float>> pts;
  pts.reserve(n);
  for (size_t i = 0; i < n; ++i)
    if (std::isfinite(pred[i]) && std::isfinite(resid[i]) && pred[i] > 0)
      pts.emplace_back(pred[i], resid[i]);
  if (pts.size() < 100) fail("noise model needs at least 100 pixels, got ", pts.size());
  // Equal-count bins by predicted intensity; MAD variance per bin resists the bones.
  const int bins = int(std::clamp<size_t>(pts.size() / 200, 2, 12));
  partition_bins(pts, pts.size(), 0, bins, bins);
  std::vector<double> xs, vs, ws, tmp;
  for (int k = 0; k < bins; ++k) {
    const size_t lo = pts.size() * k / bins, hi = pts.size() * (k + 1) / bins;
    tmp.clear();
    double mean_i = 0;
    for (size_t i = lo; i < hi; ++i) {
      tmp.push_back(pts[i].second);
      mean_i += pts[i].first;
    }
    mean_i /= double(hi - lo);
    const double med = median_inplace(tmp.data(), tmp.size());
    for (double& t : tmp) t = std::abs(t - med);
    const double s = median_inplace(tmp.data(), tmp.size()) / kMadNormal;
    xs.push_back(1.0 / mean_i);
    vs.push_back(s * s);
    ws.push_back(double(hi - lo));
  }
  // v = a x + b x^2 with x = 1/I: 2x2 normal equations, falling back to one term when the
  // other would come out negative.
  double sxx = 0, sx3 = 0, sx4 = 0, sxv = 0, sx2v = 0;
  for (size_t k = 0; k < xs.size(); ++k) {
    const double x = xs[k], w = ws[k];
    sxx += w * x * x;
    sx3 += w * x * x * x;
    sx4 += w * x * x * x * x;
    sxv += w * x * vs[k];
    sx2v += w * x * x * vs[k];
  }
  NoiseModel m;
  const double det = sxx * sx4 - sx3 * sx3;
  if (det > 0) {
    m.a = (sxv * sx4 - sx2v * sx3) / det;
    m.b = (sxx * sx2v - sx3 * sxv) / det;
  }
  if (!(det > 0) || m.a < 0 || m.b < 0) {
    const double a_only = sxv / sxx, b_only = sx2v / sx4;
    // Keep the single term that fits better.
    double ea = 0, eb = 0;
    for (size_t k = 0; k < xs.size(); ++k) {
      ea += ws[k] * std::pow(vs[k] - a_only * xs[k], 2);
      eb += ws[k] * std::pow(vs[k] - b_only * xs[k] * xs[k], 2);
    }
    m = ea <= eb ? NoiseModel{std::max(a_only, 0.0), 0} : NoiseModel{0, std::max(b_only, 0.0)};
  }
  return m;
}

}  // namespace rangex
