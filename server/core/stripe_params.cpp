#include "core/stripe_params.h"

#include <array>
#include <utility>

#include "core/error.h"

namespace rangex {

namespace {
constexpr std::array<std::pair<std::string_view, StripeMethod>, 7> kMethodNames{{
    {"centroid", StripeMethod::kCentroid},
    {"squared", StripeMethod::kSquared},
    {"binary", StripeMethod::kBinary},
    {"gaussian3", StripeMethod::kGaussian3},
    {"parabola", StripeMethod::kParabola},
    {"shifted", StripeMethod::kShifted},
    {"modified", StripeMethod::kModified},
}};
}  // namespace

StripeMethod parse_stripe_method(std::string_view name) {
  for (const auto& [n, m] : kMethodNames)
    if (n == name) return m;
  std::string all;
  for (const auto& [n, m] : kMethodNames) all += (all.empty() ? "" : ", ") + std::string(n);
  fail("unknown stripe method '", name, "' (expected one of: ", all, ")");
}

std::string_view stripe_method_name(StripeMethod m) {
  for (const auto& [n, mm] : kMethodNames)
    if (mm == m) return n;
  return "?";
}

}  // namespace rangex
