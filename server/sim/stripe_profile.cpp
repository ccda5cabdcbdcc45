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

namespace {
constexpr double kTableStep = StripeKernel::kStep;
double exact_core(double dy, double sigma) {
  return 0.5 * (std::erf((dy + 0.5) / (kSqrt2 * sigma)) - std::erf((dy - 0.5) / (kSqrt2 * sigma)));
}
}  // namespace

StripeKernel::StripeKernel(double sigma, double tail_px) : sigma_(sigma), tail_px_(tail_px) {
  core_x0_ = -(6 * sigma + 1);
  for (double x = core_x0_; x <= -core_x0_ + kTableStep; x += kTableStep)
    core_.push_back(exact_core(x, sigma));
  tail_x0_ = -(6 * sigma + 1);
  for (double x = tail_x0_; x <= 8 * tail_px + 6 * sigma + 1; x += kTableStep)
    tail_.push_back(emg(x, sigma, tail_px));
}

double StripeKernel::core(double dy) const {
  return core_table().at(dy);
}
double StripeKernel::tail(double x) const {
  return tail_table().at(x);
}

namespace {
// add_stripe's rows with a kernel's tables: the same arithmetic, with everything the loop
// reads held in locals (a store through the uint8_t column may alias any memory, so fields
// read through a pointer or reference would be loaded again for every row).
void add_rows(uint8_t* column, int stride, int y0, int y1, const StripeShape& s, double energy,
              double keep, double fresh, double e, Rng& rng, const StripeKernel& kernel) {
  const StripeKernel::Table core_t = kernel.core_table(), tail_t = kernel.tail_table();
  const double center = s.center, tail_w = s.tail, speckle = s.speckle;
  const int sign = s.tail_sign;
  Rng r = rng;
  for (int y = y0; y <= y1; ++y) {
    const double dy = y - center;
    const double core = core_t.at(dy);
    const double tail = tail_w > 0 ? tail_w * tail_t.at(sign * dy) : 0.0;
    double n = 0;
    if (speckle > 0) n = keep > 0 ? (e = keep * e + fresh * r.fast_normal()) : r.fast_normal();
    double v = energy * (core + tail) * (speckle > 0 ? 1 + speckle * n : 1.0);
    uint8_t& px = column[size_t(y) * stride];
    v += px;
    px = uint8_t(std::clamp(v + 0.5, 0.0, 255.0));
  }
  rng = r;
}
}  // namespace

void add_stripe(uint8_t* column, int height, int stride, const StripeShape& s, Rng& rng,
                const StripeKernel* kernel) {
  if (kernel && (kernel->sigma() != s.sigma || kernel->tail_px() != s.tail_px)) kernel = nullptr;
  const double energy = s.amplitude * s.sigma * kSqrt2Pi;
  const double reach_lo = 6 * s.sigma + (s.tail_sign < 0 ? 8 * s.tail_px : 0);
  const double reach_hi = 6 * s.sigma + (s.tail_sign > 0 ? 8 * s.tail_px : 0);
  const int y0 = std::max(0, int(std::floor(s.center - reach_lo)));
  const int y1 = std::min(height - 1, int(std::ceil(s.center + reach_hi)));
  // Correlated speckle: an AR(1) sequence down the column with unit variance.
  const double keep = s.speckle_rho, fresh = std::sqrt(1 - keep * keep);
  double e = keep > 0 ? rng.fast_normal() : 0.0;
  if (kernel) return add_rows(column, stride, y0, y1, s, energy, keep, fresh, e, rng, *kernel);
  for (int y = y0; y <= y1; ++y) {
    const double dy = y - s.center;
    const double core = exact_core(dy, s.sigma);
    const double tail = s.tail > 0 ? s.tail * emg(s.tail_sign * dy, s.sigma, s.tail_px) : 0.0;
    double n = 0;
    if (s.speckle > 0)
      n = keep > 0 ? (e = keep * e + fresh * rng.fast_normal()) : rng.fast_normal();
    double v = energy * (core + tail) * (s.speckle > 0 ? 1 + s.speckle * n : 1.0);
    uint8_t& px = column[size_t(y) * stride];
    v += px;
    px = uint8_t(std::clamp(v + 0.5, 0.0, 255.0));
  }
}

}  // namespace rangex::sim
