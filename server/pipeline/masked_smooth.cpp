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

namespace {
// One masked pass of kernel k along the step (dx, dy), on numerator and weight images.
void pass(const std::vector<float>& k, int dx, int dy, int rows, int cols,
          const std::vector<float>& num, const std::vector<float>& den, std::vector<float>& onum,
          std::vector<float>& oden) {
  const int r = int(k.size() / 2);
  onum.assign(num.size(), 0.f);
  oden.assign(num.size(), 0.f);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      float a = 0, b = 0;
      for (int d = -r; d <= r; ++d) {
        const int xx = x + d * dx, yy = y + d * dy;
        if (xx < 0 || xx >= cols || yy < 0 || yy >= rows) continue;
        const size_t j = size_t(yy) * cols + xx;
        a += k[d + r] * num[j];
        b += k[d + r] * den[j];
      }
      onum[size_t(y) * cols + x] = a;
      oden[size_t(y) * cols + x] = b;
    }
}
}  // namespace

double masked_line_gaussian(const float* v, const uint8_t* mask, int rows, int cols,
                            double sigma_along, double sigma_across, int direction,
                            std::vector<float>& out) {
  static constexpr int kStep[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
  const int dx = kStep[direction & 3][0], dy = kStep[direction & 3][1];
  const bool diagonal = dx != 0 && dy != 0;
  // A diagonal step is sqrt(2) pixels long.
  const auto ka = kernel(diagonal ? sigma_along / std::sqrt(2.0) : sigma_along);
  const auto kc = kernel(sigma_across);
  const size_t n = size_t(rows) * cols;
  std::vector<float> num(n), den(n), tnum, tden, unum, uden;
  for (size_t i = 0; i < n; ++i) {
    num[i] = mask[i] ? v[i] : 0.f;
    den[i] = mask[i] ? 1.f : 0.f;
  }
  pass(ka, dx, dy, rows, cols, num, den, tnum, tden);
  const int cx = diagonal ? 1 : dy, cy = diagonal ? 0 : dx;  // across (rows for diagonals)
  pass(kc, cx, cy, rows, cols, tnum, tden, unum, uden);
  out.assign(n, std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < n; ++i)
    if (mask[i] && uden[i] > 0) out[i] = unum[i] / uden[i];
  double sa = 0, sc = 0;
  for (float a : ka) sa += double(a) * a;
  for (float c : kc) sc += double(c) * c;
  return std::sqrt(sa * sc);
}

}  // namespace rangex
