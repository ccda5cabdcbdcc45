// A lane's `xray` section: the fan beam and its detector, the sandwich detector's layers and
// the dual-energy wedge's fit, each value checked against what a rig can be.
#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/config_yaml.h"

namespace rangex {

namespace {

// xray.dual_energy (rangexctl calib dual-energy writes it): the wedge's fit as the kernels
// read it (kernels/shared/dual_energy.h).
void read_dual_energy(const ConfigNode& n, FanBeam& x) {
  n.only_keys({"low", "high", "minv", "basis", "var_a", "var_b", "gain_low", "gain_high",
               "var_e_low", "var_e_high", "var_t", "fitted_on"});
  kernel::DualEnergyK& k = x.dual_energy;
  auto copy = [&](const char* key, double* out, size_t count) {
    const std::vector<double> v = number_list(n.at(key), count);
    std::copy(v.begin(), v.end(), out);
  };
  copy("low", k.low, DE_TERMS);
  copy("high", k.high, DE_TERMS);
  copy("minv", k.minv, 9);
  copy("basis", k.basis, 6);
  for (auto [key, out, positive] :
       {std::tuple{"var_a", &k.var_a, false}, std::tuple{"var_b", &k.var_b, false},
        std::tuple{"gain_low", &k.gain_low, true}, std::tuple{"gain_high", &k.gain_high, true},
        std::tuple{"var_e_low", &k.var_e_low, false},
        std::tuple{"var_e_high", &k.var_e_high, false}, std::tuple{"var_t", &k.var_t, false}}) {
    if (!n.has(key)) n.bad(std::string("missing '") + key + "'");
    n.get(key, *out);
    if (!(positive ? *out > 0 : *out >= 0) || !std::isfinite(*out))
      n.at(key).bad(positive ? "must be > 0" : "must be >= 0");
  }
  n.get("fitted_on", x.dual_energy_fitted_on);
  x.has_dual_energy = true;
}

}  // namespace

void read_xray(const ConfigNode& n, FanBeam& x) {
  n.only_keys({"pixels", "pitch_mm", "first_pixel_x_mm", "detector_z_mm", "source_mm", "tilt_deg",
               "delay_lines", "bits", "detector_sigma_px", "focal_spot_sigma_mm",
               "measured_delay_lines", "plane_alpha_deg", "plane_beta_deg", "energies", "sandwich",
               "dual_energy"});
  n.positive("pixels", x.pixels);
  n.positive("pitch_mm", x.pitch_mm);
  n.get("first_pixel_x_mm", x.first_pixel_x_mm);
  n.get("detector_z_mm", x.detector_z_mm);
  if (x.detector_z_mm > 0)
    n.at("detector_z_mm").bad("the detector must be below the belt (z <= 0)");
  if (n.has("source_mm")) {
    const auto v = n.at("source_mm").numbers(2);
    x.source_x_mm = v[0];
    x.source_z_mm = v[1];
  }
  if (x.source_z_mm < 100)
    n.at("source_mm").bad("the source must be at least 100 mm above the belt");
  n.get("tilt_deg", x.tilt_deg);
  n.get("detector_sigma_px", x.detector_sigma_px);
  n.get("focal_spot_sigma_mm", x.focal_spot_sigma_mm);
  if (!(x.detector_sigma_px >= 0 && x.detector_sigma_px < 20))
    n.at("detector_sigma_px").bad("must be within 0..20 px");
  if (!(x.focal_spot_sigma_mm >= 0 && x.focal_spot_sigma_mm < 10))
    n.at("focal_spot_sigma_mm").bad("must be within 0..10 mm");
  if (!(std::abs(x.tilt_deg) <= 10))
    n.at("tilt_deg").bad("must be within +-10 degrees (a detector line, not a second plane)");
  n.get("delay_lines", x.delay_lines);
  if (x.delay_lines < 0) n.at("delay_lines").bad("must be >= 0");
  n.get("measured_delay_lines", x.measured_delay_lines);
  if (x.measured_delay_lines != 0 && !(std::abs(x.measured_delay_lines - x.delay_lines) <= 1))
    n.at("measured_delay_lines").bad("must be within one line of delay_lines");
  n.get("plane_alpha_deg", x.plane_alpha_deg);
  n.get("plane_beta_deg", x.plane_beta_deg);
  for (const auto& [key, deg] : {std::pair{"plane_alpha_deg", x.plane_alpha_deg},
                                 std::pair{"plane_beta_deg", x.plane_beta_deg}})
    if (!(std::abs(deg) <= 5))
      n.at(key).bad("must be within +-5 degrees (the planes are near parallel)");
  n.get("bits", x.bits);
  if (x.bits < 8 || x.bits > 16) n.at("bits").bad("must be 8..16");
  n.get("energies", x.energies);
  if (x.energies != 1 && x.energies != 2)
    n.at("energies").bad("must be 1 or 2 (2: a sandwich detector's low and high lines)");
  if (n.has("sandwich")) {
    if (x.energies != 2) n.at("sandwich").bad("is for energies: 2");
    const ConfigNode d = n.at("sandwich");
    d.only_keys(
        {"kvp", "tube_filter_al_mm", "front_csi_mm", "filter_cu_mm", "back_csi_mm", "low_photons"});
    SandwichDetector& sd = x.sandwich;
    d.get("kvp", sd.kvp);
    d.get("tube_filter_al_mm", sd.tube_filter_al_mm);
    d.get("front_csi_mm", sd.front_csi_mm);
    d.get("filter_cu_mm", sd.filter_cu_mm);
    d.get("back_csi_mm", sd.back_csi_mm);
    d.positive("low_photons", sd.low_photons);
    try {
      layer_spectra(sd);
    } catch (const Error& e) {
      d.bad(e.what());
    }
  }
  if (n.has("dual_energy")) {
    if (x.energies != 2) n.at("dual_energy").bad("is for energies: 2");
    read_dual_energy(n.at("dual_energy"), x);
  }
}

}  // namespace rangex
