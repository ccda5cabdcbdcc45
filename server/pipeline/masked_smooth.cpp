#include "pipeline/masked_smooth.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rangex {

namespace {
int radius(double sigma) {
  return std::max(1, int(std::ceil(3 * sigma)));
}
std::vector<float> gauss_taps(double sigma) {
  const int r = radius(sigma);
  std::vector<float> k(2 * r + 1);
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += k[i + r] = float(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (auto& v : k) v = float(v / sum);
  return k;
}
}  // namespace

int smooth_reach_px(double sigma_along, double sigma_across) {
  return radius(sigma_along) + (sigma_across > 0 ? radius(sigma_across) : 0);
}

double gaussian_noise_gain(double sigma) {
  const auto k = gauss_taps(sigma);
  double s = 0;
  for (float a : k) s += double(a) * a;
  return s;  // separable: (sum k_i^2)(sum k_j^2) under the root
}

namespace {
// One pass of kernel k along the step (dx, dy) on numerator and weight images, zero outside.
// Row by row and tap by tap, so that the inner loop runs over contiguous columns (and
// vectorises); each output still sums its taps from -r to r, as a per-pixel loop would.
void pass(const std::vector<float>& k, int dx, int dy, int rows, int cols,
          const std::vector<float>& num, const std::vector<float>& den, std::vector<float>& onum,
          std::vector<float>& oden) {
  const int r = int(k.size() / 2);
  onum.assign(num.size(), 0.f);
  oden.assign(num.size(), 0.f);
  for (int y = 0; y < rows; ++y) {
    float* a = onum.data() + size_t(y) * cols;
    float* b = oden.data() + size_t(y) * cols;
    for (int d = -r; d <= r; ++d) {
      const int yy = y + d * dy;
      if (yy < 0 || yy >= rows) continue;
      const int shift = d * dx;
      const int x0 = std::max(0, -shift), x1 = std::min(cols, cols - shift);
      const float kd = k[d + r];
      // Row starts, indexed at x + shift inside [0, cols): a pointer shifted off the row
      // beforehand could point outside the image, which C++ leaves undefined.
      const float* pn = num.data() + size_t(yy) * cols;
      const float* pd = den.data() + size_t(yy) * cols;
      for (int x = x0; x < x1; ++x) {
        a[x] += kd * pn[x + shift];
        b[x] += kd * pd[x + shift];
      }
    }
  }
}
}  // namespace

namespace {
// Two passes (kernel k1 along (x1, y1), then k2 along (x2, y2)) of the normalised
// convolution: numerator v m and weight m, divided inside the mask.
void masked_two_pass(const float* v, const uint8_t* mask, int rows, int cols,
                     const std::vector<float>& k1, int x1, int y1, const std::vector<float>& k2,
                     int x2, int y2, std::vector<float>& out) {
  const size_t n = size_t(rows) * cols;
  std::vector<float> num(n), den(n), tnum, tden, unum, uden;
  for (size_t i = 0; i < n; ++i) {
    num[i] = mask[i] ? v[i] : 0.f;
    den[i] = mask[i] ? 1.f : 0.f;
  }
  pass(k1, x1, y1, rows, cols, num, den, tnum, tden);
  pass(k2, x2, y2, rows, cols, tnum, tden, unum, uden);
  out.assign(n, std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < n; ++i)
    if (mask[i] && uden[i] > 0) out[i] = unum[i] / uden[i];
}
}  // namespace

void masked_gaussian(const float* v, const uint8_t* mask, int rows, int cols, double sigma,
                     std::vector<float>& out) {
  const auto k = gauss_taps(sigma);
  masked_two_pass(v, mask, rows, cols, k, 1, 0, k, 0, 1, out);  // along rows, then columns
}

namespace {
// Kernel steps of a line direction: along (dx, dy), across (cx, cy), as masked_line_gaussian.
struct LineSteps {
  int dx, dy, cx, cy;
  bool diagonal;
};
LineSteps line_steps(int direction) {
  static constexpr int kStep[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
  const int dx = kStep[direction & 3][0], dy = kStep[direction & 3][1];
  const bool diagonal = dx != 0 && dy != 0;
  return {dx, dy, diagonal ? 1 : dy, diagonal ? 0 : dx, diagonal};
}
}  // namespace

double masked_smooth_at(const float* v, const uint8_t* mask, int rows, int cols, double sigma_along,
                        double sigma_across, int direction, int r, int c) {
  // The kernels' product summed over the window, the mask's weights normalised.
  const bool round = direction < 0;
  const LineSteps st = round ? LineSteps{1, 0, 0, 1, false} : line_steps(direction);
  const std::vector<float> ka =
      gauss_taps(st.diagonal ? sigma_along / std::sqrt(2.0) : sigma_along);
  const std::vector<float> kc = round ? ka : gauss_taps(sigma_across);
  const int ra = int(ka.size() / 2), rc = int(kc.size() / 2);
  double num = 0, den = 0;
  for (int a = -ra; a <= ra; ++a)
    for (int b = -rc; b <= rc; ++b) {
      const int x = c + a * st.dx + b * st.cx, y = r + a * st.dy + b * st.cy;
      if (x < 0 || x >= cols || y < 0 || y >= rows) continue;
      const size_t j = size_t(y) * cols + x;
      if (!mask[j]) continue;
      const double w = double(ka[a + ra]) * kc[b + rc];
      num += w * v[j], den += w;
    }
  return den > 0 ? num / den : std::numeric_limits<double>::quiet_NaN();
}

double masked_line_gaussian(const float* v, const uint8_t* mask, int rows, int cols,
                            double sigma_along, double sigma_across, int direction,
                            std::vector<float>& out) {
  const LineSteps st = line_steps(direction);
  // A diagonal step is sqrt(2) pixels long; across a diagonal is along the rows.
  const auto ka = gauss_taps(st.diagonal ? sigma_along / std::sqrt(2.0) : sigma_along);
  const auto kc = gauss_taps(sigma_across);
  masked_two_pass(v, mask, rows, cols, ka, st.dx, st.dy, kc, st.cx, st.cy, out);
  double sa = 0, sc = 0;
  for (float a : ka) sa += double(a) * a;
  for (float c : kc) sc += double(c) * c;
  return std::sqrt(sa * sc);
}

}  // namespace rangex
