// What the X-ray passes through, by photon energy: mass attenuation coefficients (mu/rho,
// cm^2/g) of the materials rangex meets or calibrates with, from NIST's tables (Hubbell &
// Seltzer, NISTIR 5632: tables 3 and 4; the tissues' compositions are ICRU Report 44's),
// interpolated log-log between the tabulated energies as NIST advises (absorption edges are
// tabulated twice). Linear attenuation = mu/rho x density.
//
// Tissues that NIST does not tabulate are built from ones it does (assumptions, stated):
// cartilage and tendon are soft tissue (muscle's mu/rho) at their own densities (1.10,
// 1.12 g/cm^3, ICRP 89); bone calcified to c (0..1) is, by volume, c of cortical bone and
// 1 - c of cartilage.
#pragma once
#include <string>

namespace rangex {

enum class Material {
  kAir,
  kLean,       // muscle, skeletal (ICRU-44), 1.05 g/cm^3
  kFat,        // adipose tissue (ICRU-44), 0.95
  kCartilage,  // soft tissue at 1.10
  kTendon,     // soft tissue at 1.12
  kBone,       // cortical bone (ICRU-44), 1.92: fully calcified
  kA150,       // A-150 tissue-equivalent plastic, 1.127: the soft step wedge
  kAluminium,  // 2.699: the bone-equivalent step wedge
  kCopper,     // 8.96: the sandwich detector's filter
  kCsI,        // caesium iodide, 4.51: the detector's scintillator
};

const char* material_name(Material m);
// Material by name ("lean", "fat", "cartilage", ...); throws Error naming the known ones.
Material material_named(const std::string& name);

double density_g_cm3(Material m);
// mu/rho at energy_kev (10..150 keV), cm^2/g.
double mass_attenuation(Material m, double energy_kev);
// Linear attenuation, per mm.
double attenuation_per_mm(Material m, double energy_kev);
// Bone calcified to c: per mm, by volume c of cortical bone and 1 - c of cartilage.
double bone_attenuation_per_mm(double calcification, double energy_kev);

}  // namespace rangex
