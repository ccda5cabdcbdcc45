// A lane's `inspection` section: the decision's settings, each checked against its range,
// with the learned thresholds (learned_detection_yaml.cpp) when a learning wrote them.
#include <string>
#include <vector>

#include "core/config_yaml.h"

namespace rangex {

namespace {

// How fillets are cut from the lane, the gaps in their thickness closed, and the thickness
// mapped to attenuation.
void read_fit_settings(const ConfigNode& n, InspectionParams& q) {
  n.positive("floor_mm", q.floor_mm);
  n.positive("min_fillet_area_mm2", q.min_fillet_area_mm2);
  n.positive("gap_lines", q.gap_lines);
  n.positive("max_segment_lines", q.max_segment_lines);
  n.get("max_invalid_fraction", q.max_invalid_fraction);
  if (q.max_invalid_fraction < 0 || q.max_invalid_fraction > 1)
    n.at("max_invalid_fraction").bad("must be in [0, 1]");
  n.get("attenuation_degree", q.attenuation_degree);
  if (q.attenuation_degree != 1 && q.attenuation_degree != 2)
    n.at("attenuation_degree").bad("must be 1 (a line) or 2 (a parabola, for beam hardening)");
  n.positive("tukey_c", q.tukey_c);
  n.positive("max_iter", q.max_iter);
  n.positive("tol", q.tol);
  n.positive("encoder_horizon_lines", q.encoder_horizon_lines);
  n.get("rim_walls", q.rim_walls);
  n.get("max_wall_gap_px", q.max_wall_gap_px);
  if (q.max_wall_gap_px < 0 || q.max_wall_gap_px > 20)
    n.at("max_wall_gap_px").bad("must be within 0..20 (0: never close a wall's rim)");
}

// The detection's statistics, fixed thresholds and floors (learned ones: read_learned).
void read_detection_settings(const ConfigNode& n, InspectionParams& q) {
  n.positive("smooth_sigma_px", q.smooth_sigma_px);
  n.positive("z_threshold", q.z_threshold);
  n.positive("min_fragment_area_mm2", q.min_fragment_area_mm2);
  n.get("min_fragment_meat_mm", q.min_fragment_meat_mm);
  if (!(q.min_fragment_meat_mm >= 0 && q.min_fragment_meat_mm <= 20))
    n.at("min_fragment_meat_mm").bad("must be within 0..20 mm (0: off)");
  n.get("require_added_attenuation", q.require_added_attenuation);
  n.positive("air_z_threshold", q.air_z_threshold);
  if (n.has("spread")) q.spread_by_thickness = read_spread(n.at("spread"));
  n.get("false_reject_target", q.false_reject_target);
  if (!(q.false_reject_target > 0 && q.false_reject_target < 0.5))
    n.at("false_reject_target").bad("must be in (0, 0.5), a fraction of fillets");
  n.positive("min_air_area_mm2", q.min_air_area_mm2);
  n.positive("baseline_sigma_mm", q.baseline_sigma_mm);
  n.get("line_sigma_along_px", q.line_sigma_along_px);
  if (!(q.line_sigma_along_px >= 0 && q.line_sigma_along_px <= 20))
    n.at("line_sigma_along_px").bad("must be within 0..20 (0: no needle kernels)");
  n.positive("line_sigma_across_px", q.line_sigma_across_px);
}

// The kernels whitened by the product's texture, and how they clip bright values.
void read_matched_settings(const ConfigNode& n, InspectionParams& q) {
  if (n.has("matched_kernels_mm")) {
    q.matched_kernels_mm = number_list(n.at("matched_kernels_mm"), 0);
    for (double d : q.matched_kernels_mm)
      if (!(d >= 0.5 && d <= 6))
        n.at("matched_kernels_mm").bad("sphere sizes must be within 0.5..6 mm");
  }
  n.get("matched_clip", q.matched_clip);
  if (!(q.matched_clip >= 0.5 && q.matched_clip <= 100))
    n.at("matched_clip").bad("must be within 0.5..100 robust spreads");
  n.get("matched_enclosure", q.matched_enclosure);
  n.get("matched_void_factor", q.matched_void_factor);
  if (!(q.matched_void_factor == 0 || (q.matched_void_factor >= 1 && q.matched_void_factor <= 100)))
    n.at("matched_void_factor").bad("must be 0 (no voids) or within 1..100");
  if (n.has("matched_needles_mm")) {
    q.matched_needles_mm = number_list(n.at("matched_needles_mm"), 0);
    for (double d : q.matched_needles_mm)
      if (!(d >= 1 && d <= 6))
        n.at("matched_needles_mm").bad("needle lengths must be within 1..6 mm");
  }
  if (n.has("matched_needle_diameter_mm")) {
    const ConfigNode d = n.at("matched_needle_diameter_mm");
    q.matched_needle_diameters_mm =
        d.node.IsSequence() ? number_list(d, 0) : std::vector<double>{d.num()};
    if (q.matched_needle_diameters_mm.empty()) d.bad("expected a diameter or a list of them");
    for (double x : q.matched_needle_diameters_mm)
      if (!(x >= 0.2 && x <= 2)) d.bad("must be within 0.2..2 mm");
  }
}

// Dual energy: the method, and how much the soft tissue's density varies.
void read_dual_energy_settings(const ConfigNode& n, InspectionParams& q) {
  if (n.has("dual_energy")) {
    const std::string m = n.at("dual_energy").str();
    if (m == "laser")
      q.dual_energy = DualEnergyMethod::kLaser;
    else if (m == "no_laser")
      q.dual_energy = DualEnergyMethod::kNoLaser;
    else if (m == "low_line")
      q.dual_energy = DualEnergyMethod::kLowLine;
    else if (m == "laser_and_low_line")
      q.dual_energy = DualEnergyMethod::kLaserAndLowLine;
    else
      n.at("dual_energy")
          .bad("'" + m + "': expected laser, no_laser, low_line or laser_and_low_line");
  }
  n.get("soft_density_sigma", q.soft_density_sigma);
  if (!(q.soft_density_sigma >= 0 && q.soft_density_sigma <= 0.5))
    n.at("soft_density_sigma").bad("must be within 0..0.5 (a relative sigma)");
}

}  // namespace

void read_inspection(const ConfigNode& n, InspectionParams& q) {
  n.only_keys({"floor_mm",
               "min_fillet_area_mm2",
               "gap_lines",
               "max_segment_lines",
               "max_invalid_fraction",
               "tukey_c",
               "max_iter",
               "tol",
               "smooth_sigma_px",
               "z_threshold",
               "min_fragment_area_mm2",
               "air_z_threshold",
               "min_air_area_mm2",
               "baseline_sigma_mm",
               "soft_density_sigma",
               "encoder_horizon_lines",
               "max_wall_gap_px",
               "rim_walls",
               "line_sigma_along_px",
               "line_sigma_across_px",
               "attenuation_degree",
               "min_fragment_meat_mm",
               "require_added_attenuation",
               "false_reject_target",
               "matched_kernels_mm",
               "matched_clip",
               "matched_enclosure",
               "matched_void_factor",
               "matched_needles_mm",
               "matched_needle_diameter_mm",
               "learned",
               "spread",
               "dual_energy"});
  read_fit_settings(n, q);
  read_detection_settings(n, q);
  read_matched_settings(n, q);
  if (n.has("learned")) read_learned(n.at("learned"), q.learned);
  read_dual_energy_settings(n, q);
}

}  // namespace rangex
