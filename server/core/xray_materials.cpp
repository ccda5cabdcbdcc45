#include "core/xray_materials.h"

#include <cmath>
#include <iterator>
#include <utility>

#include "core/error.h"

namespace rangex {

namespace {

using Point = std::pair<double, double>;  // keV, mu/rho in cm^2/g

// NISTIR 5632, tables 3 and 4, 10-150 keV (absorption edges twice: below, above).
constexpr Point kMuscle[] = {{10, 5.356},   {15, 1.693},  {20, 0.8205}, {30, 0.3783},
                             {40, 0.2685},  {50, 0.2262}, {60, 0.2048}, {80, 0.1823},
                             {100, 0.1693}, {150, 0.1492}};
constexpr Point kAdipose[] = {{10, 3.268},   {15, 1.083},  {20, 0.5677}, {30, 0.3063},
                              {40, 0.2396},  {50, 0.2123}, {60, 0.1974}, {80, 0.1800},
                              {100, 0.1688}, {150, 0.1500}};
constexpr Point kCortical[] = {{10, 28.51},   {15, 9.032},  {20, 4.001},  {30, 1.331},
                               {40, 0.6655},  {50, 0.4242}, {60, 0.3148}, {80, 0.2229},
                               {100, 0.1855}, {150, 0.1480}};
constexpr Point kA150[] = {{10, 4.186},  {15, 1.394},  {20, 0.7068}, {30, 0.3481},  {40, 0.2562},
                           {50, 0.2198}, {60, 0.2008}, {80, 0.1803}, {100, 0.1680}, {150, 0.1485}};
constexpr Point kAl[] = {{10, 26.23},  {15, 7.955},  {20, 3.441},  {30, 1.128},   {40, 0.5685},
                         {50, 0.3681}, {60, 0.2778}, {80, 0.2018}, {100, 0.1704}, {150, 0.1378}};
constexpr Point kCu[] = {{10, 215.9}, {15, 74.05}, {20, 33.79},  {30, 10.92},   {40, 4.862},
                         {50, 2.613}, {60, 1.593}, {80, 0.7630}, {100, 0.4584}, {150, 0.2217}};
constexpr Point kCsI[] = {{10, 171.1},      {15, 58.15},      {20, 26.86},      {30, 9.045},
                          {33.1694, 6.923}, {33.1694, 21.22}, {34.5483, 26.87}, {35.9846, 17.19},
                          {35.9846, 30.27}, {40, 22.97},      {50, 12.87},      {60, 7.921},
                          {80, 3.677},      {100, 2.035},     {150, 0.7290}};

template <size_t N>
double interpolate(const Point (&t)[N], double e) {
  if (!(e >= t[0].first && e <= t[N - 1].first))
    fail("X-ray energy ", e, " keV is outside the tables' ", t[0].first, "..", t[N - 1].first,
         " keV");
  for (size_t i = 0; i + 1 < N; ++i) {
    const auto [e0, m0] = t[i];
    const auto [e1, m1] = t[i + 1];
    if (e1 <= e0 || e > e1) continue;  // an edge's two values, or not yet
    const double f = std::log(e / e0) / std::log(e1 / e0);
    return std::exp(std::log(m0) + f * (std::log(m1) - std::log(m0)));
  }
  return t[N - 1].second;
}

struct Named {
  Material m;
  const char* name;
  double density;
};
constexpr Named kMaterials[] = {
    {Material::kAir, "air", 0.0},        {Material::kLean, "lean", 1.05},
    {Material::kFat, "fat", 0.95},       {Material::kCartilage, "cartilage", 1.10},
    {Material::kTendon, "tendon", 1.12}, {Material::kBone, "bone", 1.92},
    {Material::kA150, "a150", 1.127},    {Material::kAluminium, "aluminium", 2.699},
    {Material::kCopper, "copper", 8.96}, {Material::kCsI, "csi", 4.51},
};

const Named& named(Material m) {
  for (const Named& n : kMaterials)
    if (n.m == m) return n;
  fail("unknown material ", int(m));
}

}  // namespace

const char* material_name(Material m) {
  return named(m).name;
}

Material material_named(const std::string& name) {
  std::string known;
  for (const Named& n : kMaterials) {
    if (name == n.name) return n.m;
    known += (known.empty() ? "" : ", ") + std::string(n.name);
  }
  fail("unknown material '", name, "' (", known, ")");
}

double density_g_cm3(Material m) {
  return named(m).density;
}

double mass_attenuation(Material m, double e) {
  switch (m) {
    case Material::kAir:
      return 0;  // 1.2 mg/cm^3: nothing over a belt's few centimetres
    case Material::kLean:
    case Material::kCartilage:
    case Material::kTendon:
      return interpolate(kMuscle, e);
    case Material::kFat:
      return interpolate(kAdipose, e);
    case Material::kBone:
      return interpolate(kCortical, e);
    case Material::kA150:
      return interpolate(kA150, e);
    case Material::kAluminium:
      return interpolate(kAl, e);
    case Material::kCopper:
      return interpolate(kCu, e);
    case Material::kCsI:
      return interpolate(kCsI, e);
  }
  return 0;
}

double attenuation_per_mm(Material m, double e) {
  return 0.1 * mass_attenuation(m, e) * density_g_cm3(m);  // cm^-1 -> mm^-1
}

double bone_attenuation_per_mm(double c, double e) {
  return c * attenuation_per_mm(Material::kBone, e) +
         (1 - c) * attenuation_per_mm(Material::kCartilage, e);
}

}  // namespace rangex
