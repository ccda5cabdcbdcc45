// The masked smoothing (separable, row by row) against the direct 2D sum of its definition:
// out(p) = sum_q K(p - q) m(q) v(q) / sum_q K(p - q) m(q), K the product of two 1D kernels.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pipeline/masked_smooth.h"

using namespace rangex;

namespace {

std::vector<double> gauss_definition(double sigma) {  // as the definition: 3 sigma, normalised
  const int r = std::max(1, int(std::ceil(3 * sigma)));
  std::vector<double> k(2 * r + 1);
  double s = 0;
  for (int i = -r; i <= r; ++i) s += k[i + r] = std::exp(-0.5 * i * i / (sigma * sigma));
  for (double& v : k) v /= s;
  return k;
}

// Direct sum over both kernels' taps: along (ax, ay) with ka, across (cx, cy) with kc.
float direct(const std::vector<float>& v, const std::vector<uint8_t>& m, int rows, int cols, int y,
             int x, const std::vector<double>& ka, int ax, int ay, const std::vector<double>& kc,
             int cx, int cy) {
  const int ra = int(ka.size() / 2), rc = int(kc.size() / 2);
  double num = 0, den = 0;
  for (int a = -ra; a <= ra; ++a)
    for (int c = -rc; c <= rc; ++c) {
      const int xx = x + a * ax + c * cx, yy = y + a * ay + c * cy;
      if (xx < 0 || xx >= cols || yy < 0 || yy >= rows) continue;
      const size_t j = size_t(yy) * cols + xx;
      if (!m[j]) continue;
      const double w = ka[a + ra] * kc[c + rc];
      num += w * v[j], den += w;
    }
  return den > 0 ? float(num / den) : NAN;
}

struct Image {
  int rows = 37, cols = 53;
  std::vector<float> v;
  std::vector<uint8_t> m;
  Image() {
    std::mt19937 rng(3);
    std::normal_distribution<float> g(0, 1);
    std::uniform_real_distribution<float> u(0, 1);
    for (int y = 0; y < rows; ++y)
      for (int x = 0; x < cols; ++x) {
        // An ellipse of fillet with holes, so that borders and gaps are crossed.
        const double dy = (y - 18.0) / 16, dx = (x - 26.0) / 24;
        m.push_back(dx * dx + dy * dy < 1 && u(rng) > 0.1);
        v.push_back(g(rng));
      }
  }
};

}  // namespace

TEST(MaskedSmooth, GaussianEqualsItsDefinition) {
  const Image im;
  for (double sigma : {0.7, 1.0, 2.5}) {
    std::vector<float> out;
    masked_gaussian(im.v.data(), im.m.data(), im.rows, im.cols, sigma, out);
    const auto k = gauss_definition(sigma);
    int checked = 0;
    for (int y = 0; y < im.rows; ++y)
      for (int x = 0; x < im.cols; ++x) {
        const size_t i = size_t(y) * im.cols + x;
        if (!im.m[i]) {
          EXPECT_TRUE(std::isnan(out[i]));
          continue;
        }
        ASSERT_NEAR(out[i], direct(im.v, im.m, im.rows, im.cols, y, x, k, 1, 0, k, 0, 1), 2e-5)
            << "sigma " << sigma << " at " << y << "," << x;
        ++checked;
      }
    EXPECT_GT(checked, 800);
  }
}

TEST(MaskedSmooth, LineGaussianEqualsItsDefinitionInEveryDirection) {
  const Image im;
  const double along = 3.0, across = 0.7;
  // Directions: along x, along y, the two diagonals (a diagonal step is sqrt 2 long, and
  // its across step runs along x).
  const int steps[4][4] = {{1, 0, 0, 1}, {0, 1, 1, 0}, {1, 1, 1, 0}, {1, -1, 1, 0}};
  for (int dir = 0; dir < 4; ++dir) {
    std::vector<float> out;
    const double gain =
        masked_line_gaussian(im.v.data(), im.m.data(), im.rows, im.cols, along, across, dir, out);
    const auto ka = gauss_definition(dir >= 2 ? along / std::sqrt(2.0) : along),
               kc = gauss_definition(across);
    double sa = 0, sc = 0;
    for (double a : ka) sa += a * a;
    for (double c : kc) sc += c * c;
    EXPECT_NEAR(gain, std::sqrt(sa * sc), 1e-6);
    for (int y = 0; y < im.rows; ++y)
      for (int x = 0; x < im.cols; ++x) {
        const size_t i = size_t(y) * im.cols + x;
        if (!im.m[i]) continue;
        ASSERT_NEAR(out[i],
                    direct(im.v, im.m, im.rows, im.cols, y, x, ka, steps[dir][0], steps[dir][1], kc,
                           steps[dir][2], steps[dir][3]),
                    2e-5)
            << "direction " << dir << " at " << y << "," << x;
      }
  }
}

TEST(MaskedSmooth, OnePixelEqualsTheWholeImage) {
  const Image im;
  std::vector<float> round, line;
  masked_gaussian(im.v.data(), im.m.data(), im.rows, im.cols, 1.0, round);
  for (int dir = -1; dir < 4; ++dir) {
    if (dir >= 0)
      masked_line_gaussian(im.v.data(), im.m.data(), im.rows, im.cols, 3, 0.7, dir, line);
    const std::vector<float>& want = dir < 0 ? round : line;
    for (int y = 0; y < im.rows; y += 3)
      for (int x = 0; x < im.cols; x += 2) {
        const size_t i = size_t(y) * im.cols + x;
        if (!im.m[i]) continue;
        const double got = masked_smooth_at(im.v.data(), im.m.data(), im.rows, im.cols,
                                            dir < 0 ? 1.0 : 3.0, 0.7, dir, y, x);
        ASSERT_NEAR(got, want[i], 2e-5) << "direction " << dir << " at " << y << "," << x;
      }
  }
}
