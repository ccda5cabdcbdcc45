#include "sim/stripe_profile.h"

#include <algorithm>
#include <cmath>

namespace rangex::sim {

namespace {
constexpr double kSqrt2 = 1.41421356237309515;
constexpr double kSqrt2Pi = 2.50662827463100024;

// Exponentially modified Gaussian density (tail toward +x), unit area.
double emg(double x, double sigma, double lambda) {
  const double a = sigma / lambda;
  return 0.5 / lambda * std::exp(0.5 * a * a - x / lambda) * std::erfc((a - x / sigma) / kSqrt2);
}
}  // namespace

void add_stripe(uint8_t* column, int height, int stride, const StripeShape& s, Rng& rng) {
  const double energy = s.amplitude * s.sigma * kSqrt2Pi;
  const double reach_lo = 6 * s.sigma + (s.tail_sign < 0 ? 8 * s.tail_px : 0);
  const double reach_hi = 6 * s.sigma + (s.tail_sign > 0 ? 8 * s.tail_px : 0);
  const int y0 = std::max(0, int(std::floor(s.center - reach_lo)));
  const int y1 = std::min(height - 1, int(std::ceil(s.center + reach_hi)));
  for (int y = y0; y <= y1; ++y) {
    const double dy = y - s.center;
    const double core =
        0.5 * (std::erf((dy + 0.5) / (kSqrt2 * s.sigma)) - std::erf((dy - 0.5) / (kSqrt2 * s.sigma)));
    const double tail = s.tail > 0 ? s.tail * emg(s.tail_sign * dy, s.sigma, s.tail_px) : 0.0;
    double v = energy * (core + tail) * (1 + s.speckle * rng.normal());
    uint8_t& px = column[size_t(y) * stride];
    v += px;
    px = uint8_t(std::clamp(std::lround(v), 0L, 255L));
  }
}

}  // namespace rangex::sim
