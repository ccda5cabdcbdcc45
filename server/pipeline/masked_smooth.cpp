#include "pipeline/masked_smooth.h"

#include <cmath>
#include <limits>

namespace rangex {

namespace {
std::vector<float> kernel(double sigma) {
  const int r = std::max(1, int(std::ceil(3 * sigma)));
  std::vector<float> k(2 * r + 1);
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += k[i + r] = float(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (auto& v : k) v = float(v / sum);
  return k;
}
}  // namespace

double gaussian_noise_gain(double sigma) {
  const auto k = kernel(sigma);
  double s = 0;
  for (float a : k) s += double(a) * a;
  return s;  // separable: (sum k_i^2)(sum k_j^2) under the root
}

void masked_gaussian(const float* v, const uint8_t* mask, int rows, int cols, double sigma,
                     std::vector<float>& out) {
  const auto k = kernel(sigma);
  const int r = int(k.size() / 2);
  const size_t n = size_t(rows) * cols;
  std::vector<float> num(n), den(n), tnum(n), tden(n);
  for (size_t i = 0; i < n; ++i) {
    num[i] = mask[i] ? v[i] : 0.f;
    den[i] = mask[i] ? 1.f : 0.f;
  }
  // Along rows, then along columns.
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      float a = 0, b = 0;
      for (int d = -r; d <= r; ++d) {
        const int xx = x + d;
        if (xx < 0 || xx >= cols) continue;
        const size_t j = size_t(y) * cols + xx;
        a += k[d + r] * num[j];
        b += k[d + r] * den[j];
      }
      tnum[size_t(y) * cols + x] = a;
      tden[size_t(y) * cols + x] = b;
    }
  out.assign(n, std::numeric_limits<float>::quiet_NaN());
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      const size_t i = size_t(y) * cols + x;
      if (!mask[i]) continue;
      float a = 0, b = 0;
      for (int d = -r; d <= r; ++d) {
        const int yy = y + d;
        if (yy < 0 || yy >= rows) continue;
        const size_t j = size_t(yy) * cols + x;
        a += k[d + r] * tnum[j];
        b += k[d + r] * tden[j];
      }
      out[i] = b > 0 ? a / b : std::numeric_limits<float>::quiet_NaN();
    }
}

}  // namespace rangex
