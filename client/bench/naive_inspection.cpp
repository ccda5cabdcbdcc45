#include "bench/naive_inspection.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "pipeline/connected_components.h"
#include "pipeline/masked_smooth.h"

namespace rangex {

namespace {
double sorted_median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void wls(const std::vector<double>& x, const std::vector<double>& y, const std::vector<double>& w,
         double& b0, double& b1) {
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) sw += w[i], sx += w[i] * x[i], sy += w[i] * y[i];
  const double mx = sx / sw, my = sy / sw;
  for (size_t i = 0; i < x.size(); ++i)
    sxx += w[i] * (x[i] - mx) * (x[i] - mx), sxy += w[i] * (x[i] - mx) * (y[i] - my);
  b1 = sxy / sxx;
  b0 = my - b1 * mx;
}
}  // namespace

FilletResult inspect_fillet_naive(const FilletImage& img, const InspectionParams& p) {
  FilletResult res;
  std::vector<double> x, y;
  std::vector<size_t> idx;
  for (size_t i = 0; i < img.size(); ++i)
    if (img.mask[i] && std::isfinite(img.thickness[i]) && img.xray[i] > 0) {
      x.push_back(img.thickness[i]);
      y.push_back(std::log(double(img.xray[i])));
      idx.push_back(i);
    }
  const size_t n = x.size();
  double b0, b1;
  wls(x, y, std::vector<double>(n, 1.0), b0, b1);
  double prev = 1e300;
  for (int it = 1; it < p.max_iter; ++it) {
    std::vector<double> r, a;
    for (size_t i = 0; i < n; ++i) r.push_back(y[i] - b0 - b1 * x[i]);
    for (double v : r) a.push_back(std::abs(v));
    const double s = sorted_median(a) / 0.6744897501960817;
    std::vector<double> w;
    for (double v : r) {
      const double z = v / s / p.tukey_c;
      w.push_back(std::abs(z) <= 1 ? (1 - z * z) * (1 - z * z) : 0.0);
    }
    wls(x, y, w, b0, b1);
    double dev = 0;
    for (size_t i = 0; i < n; ++i) {
      const double z = (y[i] - b0 - b1 * x[i]) / s / p.tukey_c;
      if (std::abs(z) <= 1) dev -= std::pow(1 - z * z, 3) * p.tukey_c * p.tukey_c / 6;
    }
    if (std::abs(dev - prev) <= p.tol * std::max(1.0, std::abs(dev))) break;
    prev = dev;
  }
  res.fit.beta0 = b0;
  res.fit.beta1 = b1;
  // Noise model: 8 equal-count bins by prediction, sorted copies for every median.
  std::vector<std::pair<double, double>> pr;
  for (size_t i = 0; i < n; ++i) pr.push_back({std::exp(b0 + b1 * x[i]), y[i] - b0 - b1 * x[i]});
  std::sort(pr.begin(), pr.end());
  double sxx = 0, sxv = 0;
  const int bins = 8;
  for (int k = 0; k < bins; ++k) {
    std::vector<double> v;
    double mi = 0;
    for (size_t i = pr.size() * k / bins; i < pr.size() * (k + 1) / bins; ++i)
      v.push_back(pr[i].second), mi += pr[i].first;
    mi /= double(v.size());
    const double med = sorted_median(v);
    std::vector<double> dev;
    for (double t : v) dev.push_back(std::abs(t - med));
    const double sd = sorted_median(dev) / 0.6744897501960817;
    sxx += 1 / (mi * mi);
    sxv += sd * sd / mi;
  }
  res.noise = {sxv / sxx, 0};
  // z image, then a 2-D smoothing window gathered pixel by pixel into vectors.
  const int R = int(std::ceil(3 * p.smooth_sigma_px));
  std::vector<double> z(img.size(), NAN);
  for (size_t k = 0; k < n; ++k) {
    const double P = std::exp(b0 + b1 * x[k]);
    z[idx[k]] = (y[k] - std::log(P)) / res.noise.sigma_ln(P);
  }
  std::vector<double> zs(img.size(), NAN), all;
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      if (!std::isfinite(z[size_t(r) * img.cols + c])) continue;
      std::vector<double> vals, wts;
      for (int dr = -R; dr <= R; ++dr)
        for (int dc = -R; dc <= R; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < 0 || cc < 0 || rr >= img.rows || cc >= img.cols) continue;
          const double v = z[size_t(rr) * img.cols + cc];
          if (!std::isfinite(v)) continue;
          vals.push_back(v);
          wts.push_back(
              std::exp(-0.5 * (dr * dr + dc * dc) / (p.smooth_sigma_px * p.smooth_sigma_px)));
        }
      double a = 0, b = 0;
      for (size_t k = 0; k < vals.size(); ++k) a += wts[k] * vals[k], b += wts[k];
      zs[size_t(r) * img.cols + c] = a / b;
      all.push_back(a / b);
    }
  const double med = sorted_median(all);
  std::vector<double> dev;
  for (double v : all) dev.push_back(std::abs(v - med));
  const double sd =
      std::max(sorted_median(dev) / 0.6744897501960817, gaussian_noise_gain(p.smooth_sigma_px));
  std::vector<uint8_t> on(img.size());
  for (size_t i = 0; i < img.size(); ++i)
    on[i] = std::isfinite(zs[i]) && (zs[i] - med) / sd < -p.z_threshold;
  std::vector<int> labels;
  for (const Component& c : label_components(on.data(), img.rows, img.cols, labels))
    if (c.pixels * img.pitch_mm * img.step_mm >= p.min_fragment_area_mm2)
      res.fragments.push_back({});
  res.decision = res.fragments.empty() ? Decision::kPass : Decision::kReject;
  return res;
}

}  // namespace rangex
