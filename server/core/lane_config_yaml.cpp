// A lane's YAML: its sections read over a base lane (the plant's lanes, a lane's calibration
// file), its sensors, and its calibration written back at full precision.
#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>
#include <tuple>

#include "core/config_yaml.h"

namespace rangex {

namespace {

// The rotation nearest a matrix that is almost one (Newton-Schulz iterations toward its
// polar factor: quadratic convergence from within 1e-4).
Mat3 nearest_rotation(Mat3 R) {
  for (int k = 0; k < 8; ++k) {
    const Mat3 RtR = R.transposed() * R;
    Mat3 step;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) step(i, j) = (i == j ? 1.5 : 0.0) - 0.5 * RtR(i, j);
    R = R * step;
  }
  return R;
}

void read_camera(const ConfigNode& n, LaneCamera& cam, int w, int h) {
  n.only_keys({"name", "intrinsics", "distortion", "rotation", "center_mm", "scatter"});
  n.get("name", cam.name);
  Intrinsics k = cam.model.intrinsics();
  Distortion d = cam.model.distortion();
  Mat3 R = cam.model.rotation();
  Vec3 c = cam.model.center();
  if (n.has("intrinsics")) {
    const ConfigNode in = n.at("intrinsics");
    in.only_keys({"fx", "fy", "cx", "cy", "skew"});
    in.positive("fx", k.fx);
    in.positive("fy", k.fy);
    in.get("cx", k.cx);
    in.get("cy", k.cy);
    in.get("skew", k.skew);
  }
  if (n.has("distortion")) {
    const auto v = n.at("distortion").numbers(5);
    d = {v[0], v[1], v[2], v[3], v[4]};
  }
  if (n.has("rotation")) {
    const auto v = n.at("rotation").numbers(9);
    std::copy(v.begin(), v.end(), R.m.begin());
    const Mat3 I = R * R.transposed();
    double err = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) err = std::max(err, std::abs(I(i, j) - (i == j ? 1.0 : 0.0)));
    if (err > 1e-4 || R.det() < 0)
      n.at("rotation")
          .bad("is not a proper rotation (R*R^T deviates from I by " + std::to_string(err) +
               ", det " + std::to_string(R.det()) + ")");
    // Within the tolerance but not exact (rounded digits): the nearest rotation, so that the
    // centre kept as -R c reads back as c. Found by fuzzing: a calibration stored and read
    // again drifted by 0.5 um each time.
    if (err > 1e-12) R = nearest_rotation(R);
  }
  if (n.has("center_mm")) {
    const auto v = n.at("center_mm").numbers(3);
    c = {v[0], v[1], v[2]};
    // A rig is a metre or two across; kilometres are a typo (found by fuzzing: 43 km).
    if (std::sqrt(c.x * c.x + c.y * c.y + c.z * c.z) > 10000)
      n.at("center_mm").bad("is more than 10 m from the lane's origin");
  }
  if (n.has("scatter")) {
    const ConfigNode s = n.at("scatter");
    s.only_keys({"k1", "k2", "k2_offset", "fitted_on"});
    if (s.has("fitted_on")) cam.scatter_fitted_on = s.at("fitted_on").str();
    s.get("k1", cam.scatter.k1);
    s.get("k2", cam.scatter.k2);
    s.get("k2_offset", cam.scatter.k2_offset);
  }
  cam.model = CameraModel(k, d, R, (R * c) * -1.0, w, h);
}

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

LaneConfig read_lane(const ConfigNode& lane, const ConfigNode* defaults, LaneConfig c) {
  auto section = [&](const char* key) -> std::optional<ConfigNode> {
    if (lane.has(key)) return lane.at(key);
    if (defaults && defaults->has(key)) return defaults->at(key);
    return std::nullopt;
  };
  if (auto n = section("frame")) {
    n->only_keys({"width", "height"});
    n->positive("width", c.frame_width);
    n->positive("height", c.frame_height);
    if (c.frame_width > 8192 || c.frame_height > 4096 || c.frame_height < 8)
      n->bad("frame size " + std::to_string(c.frame_width) + "x" + std::to_string(c.frame_height) +
             " is out of range (8..8192 x 8..4096)");
  }
  if (lane.has("encoder_step_mm"))
    lane.positive("encoder_step_mm", c.encoder_step_mm);
  else if (defaults && defaults->has("encoder_step_mm"))
    defaults->positive("encoder_step_mm", c.encoder_step_mm);
  // The cameras' image size always follows the frame size.
  for (auto& cam : c.cameras)
    cam.model = CameraModel(cam.model.intrinsics(), cam.model.distortion(), cam.model.rotation(),
                            cam.model.translation(), c.frame_width, c.frame_height);
  if (auto n = section("cameras")) {
    if (!n->node.IsSequence() || n->node.size() != 2) n->bad("expected a list of 2 cameras");
    for (size_t i = 0; i < 2; ++i)
      read_camera(n->item(i), c.cameras[i], c.frame_width, c.frame_height);
  }
  if (auto n = section("laser_plane")) {
    n->only_keys({"normal", "offset_mm"});
    if (n->has("normal")) {
      const auto v = n->at("normal").numbers(3);
      const Vec3 nv{v[0], v[1], v[2]};
      if (nv.norm() < 1e-9) n->at("normal").bad("must not be the zero vector");
      c.laser.normal = nv.normalized();
    }
    n->get("offset_mm", c.laser.offset_mm);
  }
  if (auto n = section("xray")) {
    n->only_keys({"pixels", "pitch_mm", "first_pixel_x_mm", "detector_z_mm", "source_mm",
                  "tilt_deg", "delay_lines", "bits", "detector_sigma_px", "focal_spot_sigma_mm",
                  "measured_delay_lines", "plane_alpha_deg", "plane_beta_deg", "energies",
                  "sandwich", "dual_energy"});
    n->positive("pixels", c.xray.pixels);
    n->positive("pitch_mm", c.xray.pitch_mm);
    n->get("first_pixel_x_mm", c.xray.first_pixel_x_mm);
    n->get("detector_z_mm", c.xray.detector_z_mm);
    if (c.xray.detector_z_mm > 0)
      n->at("detector_z_mm").bad("the detector must be below the belt (z <= 0)");
    if (n->has("source_mm")) {
      const auto v = n->at("source_mm").numbers(2);
      c.xray.source_x_mm = v[0];
      c.xray.source_z_mm = v[1];
    }
    if (c.xray.source_z_mm < 100)
      n->at("source_mm").bad("the source must be at least 100 mm above the belt");
    n->get("tilt_deg", c.xray.tilt_deg);
    n->get("detector_sigma_px", c.xray.detector_sigma_px);
    n->get("focal_spot_sigma_mm", c.xray.focal_spot_sigma_mm);
    if (!(c.xray.detector_sigma_px >= 0 && c.xray.detector_sigma_px < 20))
      n->at("detector_sigma_px").bad("must be within 0..20 px");
    if (!(c.xray.focal_spot_sigma_mm >= 0 && c.xray.focal_spot_sigma_mm < 10))
      n->at("focal_spot_sigma_mm").bad("must be within 0..10 mm");
    if (!(std::abs(c.xray.tilt_deg) <= 10))
      n->at("tilt_deg").bad("must be within +-10 degrees (a detector line, not a second plane)");
    n->get("delay_lines", c.xray.delay_lines);
    if (c.xray.delay_lines < 0) n->at("delay_lines").bad("must be >= 0");
    n->get("measured_delay_lines", c.xray.measured_delay_lines);
    if (c.xray.measured_delay_lines != 0 &&
        !(std::abs(c.xray.measured_delay_lines - c.xray.delay_lines) <= 1))
      n->at("measured_delay_lines").bad("must be within one line of delay_lines");
    n->get("plane_alpha_deg", c.xray.plane_alpha_deg);
    n->get("plane_beta_deg", c.xray.plane_beta_deg);
    for (const auto& [key, deg] : {std::pair{"plane_alpha_deg", c.xray.plane_alpha_deg},
                                   std::pair{"plane_beta_deg", c.xray.plane_beta_deg}})
      if (!(std::abs(deg) <= 5))
        n->at(key).bad("must be within +-5 degrees (the planes are near parallel)");
    n->get("bits", c.xray.bits);
    if (c.xray.bits < 8 || c.xray.bits > 16) n->at("bits").bad("must be 8..16");
    n->get("energies", c.xray.energies);
    if (c.xray.energies != 1 && c.xray.energies != 2)
      n->at("energies").bad("must be 1 or 2 (2: a sandwich detector's low and high lines)");
    if (n->has("sandwich")) {
      if (c.xray.energies != 2) n->at("sandwich").bad("is for energies: 2");
      const ConfigNode d = n->at("sandwich");
      d.only_keys({"kvp", "tube_filter_al_mm", "front_csi_mm", "filter_cu_mm", "back_csi_mm",
                   "low_photons"});
      SandwichDetector& sd = c.xray.sandwich;
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
    if (n->has("dual_energy")) {
      if (c.xray.energies != 2) n->at("dual_energy").bad("is for energies: 2");
      read_dual_energy(n->at("dual_energy"), c.xray);
    }
  }
  if (auto n = section("stripe")) {
    n->only_keys({"method", "min_peak", "threshold_rel", "max_width"});
    if (n->has("method")) {
      try {
        c.stripe.method = parse_stripe_method(n->at("method").str());
      } catch (const Error& e) {
        n->at("method").bad(e.what());
      }
    }
    n->positive("min_peak", c.stripe.min_peak);
    if (c.stripe.min_peak > 255) n->at("min_peak").bad("must be <= 255 for Mono8 frames");
    n->get("threshold_rel", c.stripe.threshold_rel);
    if (!(c.stripe.threshold_rel > 0 && c.stripe.threshold_rel < 1))
      n->at("threshold_rel").bad("must be in (0, 1)");
    n->positive("max_width", c.stripe.max_width);
  }
  if (auto n = section("rectify")) {
    n->only_keys({"lut_step_px"});
    n->positive("lut_step_px", c.lut_step_px);
    if (c.lut_step_px > 64) n->at("lut_step_px").bad("must be <= 64");
  }
  if (auto n = section("fusion")) {
    n->only_keys({"grid_pitch_mm", "grid_x0_mm", "grid_samples", "agree_tol_mm", "max_gap_mm",
                  "max_column_step_mm"});
    n->positive("grid_pitch_mm", c.fusion.grid_pitch_mm);
    n->get("grid_x0_mm", c.fusion.grid_x0_mm);
    n->positive("grid_samples", c.fusion.grid_samples);
    n->positive("agree_tol_mm", c.fusion.agree_tol_mm);
    n->get("max_gap_mm", c.fusion.max_gap_mm);
    if (c.fusion.max_gap_mm < 0) n->at("max_gap_mm").bad("must be >= 0");
    n->positive("max_column_step_mm", c.fusion.max_column_step_mm);
  }
  if (auto n = section("inspection")) {
    InspectionParams& q = c.inspection;
    n->only_keys({"floor_mm",
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
    n->positive("floor_mm", q.floor_mm);
    n->positive("min_fillet_area_mm2", q.min_fillet_area_mm2);
    n->positive("gap_lines", q.gap_lines);
    n->positive("max_segment_lines", q.max_segment_lines);
    n->get("max_invalid_fraction", q.max_invalid_fraction);
    if (q.max_invalid_fraction < 0 || q.max_invalid_fraction > 1)
      n->at("max_invalid_fraction").bad("must be in [0, 1]");
    n->get("attenuation_degree", q.attenuation_degree);
    if (q.attenuation_degree != 1 && q.attenuation_degree != 2)
      n->at("attenuation_degree").bad("must be 1 (a line) or 2 (a parabola, for beam hardening)");
    n->positive("tukey_c", q.tukey_c);
    n->positive("max_iter", q.max_iter);
    n->positive("tol", q.tol);
    n->positive("smooth_sigma_px", q.smooth_sigma_px);
    n->positive("z_threshold", q.z_threshold);
    n->positive("min_fragment_area_mm2", q.min_fragment_area_mm2);
    n->get("min_fragment_meat_mm", q.min_fragment_meat_mm);
    if (!(q.min_fragment_meat_mm >= 0 && q.min_fragment_meat_mm <= 20))
      n->at("min_fragment_meat_mm").bad("must be within 0..20 mm (0: off)");
    n->positive("air_z_threshold", q.air_z_threshold);
    if (n->has("spread")) q.spread_by_thickness = read_spread(n->at("spread"));
    n->get("false_reject_target", q.false_reject_target);
    if (!(q.false_reject_target > 0 && q.false_reject_target < 0.5))
      n->at("false_reject_target").bad("must be in (0, 0.5), a fraction of fillets");
    if (n->has("matched_kernels_mm")) {
      q.matched_kernels_mm = number_list(n->at("matched_kernels_mm"), 0);
      for (double d : q.matched_kernels_mm)
        if (!(d >= 0.5 && d <= 6))
          n->at("matched_kernels_mm").bad("sphere sizes must be within 0.5..6 mm");
    }
    n->get("matched_clip", q.matched_clip);
    if (!(q.matched_clip >= 0.5 && q.matched_clip <= 100))
      n->at("matched_clip").bad("must be within 0.5..100 robust spreads");
    n->get("matched_enclosure", q.matched_enclosure);
    n->get("matched_void_factor", q.matched_void_factor);
    if (!(q.matched_void_factor == 0 ||
          (q.matched_void_factor >= 1 && q.matched_void_factor <= 100)))
      n->at("matched_void_factor").bad("must be 0 (no voids) or within 1..100");
    if (n->has("matched_needles_mm")) {
      q.matched_needles_mm = number_list(n->at("matched_needles_mm"), 0);
      for (double d : q.matched_needles_mm)
        if (!(d >= 1 && d <= 6))
          n->at("matched_needles_mm").bad("needle lengths must be within 1..6 mm");
    }
    if (n->has("matched_needle_diameter_mm")) {
      const ConfigNode d = n->at("matched_needle_diameter_mm");
      q.matched_needle_diameters_mm =
          d.node.IsSequence() ? number_list(d, 0) : std::vector<double>{d.num()};
      if (q.matched_needle_diameters_mm.empty()) d.bad("expected a diameter or a list of them");
      for (double x : q.matched_needle_diameters_mm)
        if (!(x >= 0.2 && x <= 2)) d.bad("must be within 0.2..2 mm");
    }
    if (n->has("learned")) read_learned(n->at("learned"), q.learned);
    if (n->has("dual_energy")) {
      const std::string m = n->at("dual_energy").str();
      if (m == "laser")
        q.dual_energy = DualEnergyMethod::kLaser;
      else if (m == "no_laser")
        q.dual_energy = DualEnergyMethod::kNoLaser;
      else if (m == "low_line")
        q.dual_energy = DualEnergyMethod::kLowLine;
      else if (m == "laser_and_low_line")
        q.dual_energy = DualEnergyMethod::kLaserAndLowLine;
      else
        n->at("dual_energy")
            .bad("'" + m + "': expected laser, no_laser, low_line or laser_and_low_line");
    }
    n->positive("min_air_area_mm2", q.min_air_area_mm2);
    n->positive("baseline_sigma_mm", q.baseline_sigma_mm);
    n->get("soft_density_sigma", q.soft_density_sigma);
    if (!(q.soft_density_sigma >= 0 && q.soft_density_sigma <= 0.5))
      n->at("soft_density_sigma").bad("must be within 0..0.5 (a relative sigma)");
    n->positive("encoder_horizon_lines", q.encoder_horizon_lines);
    n->get("line_sigma_along_px", q.line_sigma_along_px);
    if (!(q.line_sigma_along_px >= 0 && q.line_sigma_along_px <= 20))
      n->at("line_sigma_along_px").bad("must be within 0..20 (0: no needle kernels)");
    n->positive("line_sigma_across_px", q.line_sigma_across_px);
    n->get("rim_walls", q.rim_walls);
    n->get("max_wall_gap_px", q.max_wall_gap_px);
    if (q.max_wall_gap_px < 0 || q.max_wall_gap_px > 20)
      n->at("max_wall_gap_px").bad("must be within 0..20 (0: never close a wall's rim)");
  }
  return c;
}

void read_sources(const ConfigNode& n, SensorSources& s) {
  n.only_keys(
      {"cameras", "xray", "trigger", "trigger_line", "offset_y", "exposure_us", "packet_size"});
  if (!n.has("cameras")) n.bad("missing key 'cameras' (two laser cameras)");
  const ConfigNode cams = n.at("cameras");
  if (!cams.node.IsSequence() || cams.node.size() != 2)
    cams.bad("expected a list of two devices (Aravis ids or IP addresses)");
  s.cameras = {cams.item(0).str(), cams.item(1).str()};
  if (!n.has("xray")) n.bad("missing key 'xray' (the X-ray line-scan detector)");
  s.xray = n.at("xray").str();
  std::set<std::string> seen;
  for (const std::string& d : s.devices()) {
    if (d.empty()) n.bad("a device id is empty");
    if (!seen.insert(d).second) n.bad("device '" + d + "' is named twice");
  }
  if (n.has("trigger")) {
    const std::string t = n.at("trigger").str();
    if (t == "encoder")
      s.trigger = LineTrigger::kEncoder;
    else if (t == "free_run")
      s.trigger = LineTrigger::kFreeRun;
    else
      n.at("trigger").bad("must be encoder or free_run (got '" + t + "')");
  }
  n.get("trigger_line", s.trigger_line);
  n.get("offset_y", s.offset_y);
  if (n.has("offset_y") && s.offset_y < 0) n.at("offset_y").bad("must be >= 0");
  if (n.has("exposure_us")) n.positive("exposure_us", s.exposure_us);
  n.get("packet_size", s.packet_size);
  if (s.packet_size != 0 && (s.packet_size < 576 || s.packet_size > 16384))
    n.at("packet_size").bad("must be 576..16384 bytes (or 0: negotiated)");
}

LaneConfig apply_lane_calibration(const LaneConfig& base, const std::string& text,
                                  const std::string& origin) {
  const YAML::Node root = load_yaml(text, origin);
  const ConfigNode n{root, "", &origin};
  if (!root.IsMap())
    n.bad(root.IsNull() ? "is empty; expected a mapping with cameras, laser_plane, xray or "
                          "encoder_step_mm"
                        : "expected a mapping with cameras, laser_plane, xray or encoder_step_mm");
  n.only_keys({"cameras", "laser_plane", "xray", "encoder_step_mm"});
  return read_lane(n, nullptr, base);
}

std::string lane_calibration_yaml(const LaneConfig& l) {
  std::ostringstream o;
  o.precision(15);
  auto list = [&o](const double* v, int n) {
    o << "[";
    for (int i = 0; i < n; ++i) o << (i ? ", " : "") << v[i];
    o << "]";
  };
  o << "encoder_step_mm: " << l.encoder_step_mm << "\ncameras:\n";
  for (const LaneCamera& c : l.cameras) {
    const Intrinsics& k = c.model.intrinsics();
    const Distortion& d = c.model.distortion();
    const double dist[5] = {d.k1, d.k2, d.p1, d.p2, d.k3};
    const Vec3 ctr = c.model.center();
    const double centre[3] = {ctr.x, ctr.y, ctr.z};
    o << "  - name: " << yaml_string(c.name) << "\n    intrinsics: {fx: " << k.fx
      << ", fy: " << k.fy << ", cx: " << k.cx << ", cy: " << k.cy << ", skew: " << k.skew
      << "}\n    distortion: ";
    list(dist, 5);
    o << "\n    rotation: ";
    list(c.model.rotation().m.data(), 9);
    o << "\n    center_mm: ";
    list(centre, 3);
    o << "\n    scatter: {k1: " << c.scatter.k1 << ", k2: " << c.scatter.k2
      << ", k2_offset: " << c.scatter.k2_offset;
    if (!c.scatter_fitted_on.empty()) o << ", fitted_on: " << yaml_string(c.scatter_fitted_on);
    o << "}\n";
  }
  const double n[3] = {l.laser.normal.x, l.laser.normal.y, l.laser.normal.z};
  o << "laser_plane: {normal: ";
  list(n, 3);
  o << ", offset_mm: " << l.laser.offset_mm << "}\n";
  const FanBeam& x = l.xray;
  o << "xray:\n  pixels: " << x.pixels << "\n  pitch_mm: " << x.pitch_mm
    << "\n  first_pixel_x_mm: " << x.first_pixel_x_mm << "\n  detector_z_mm: " << x.detector_z_mm
    << "\n  source_mm: [" << x.source_x_mm << ", " << x.source_z_mm
    << "]\n  tilt_deg: " << x.tilt_deg << "\n  delay_lines: " << x.delay_lines
    << "\n  bits: " << x.bits << "\n  detector_sigma_px: " << x.detector_sigma_px
    << "\n  focal_spot_sigma_mm: " << x.focal_spot_sigma_mm
    << "\n  measured_delay_lines: " << x.measured_delay_lines
    << "\n  plane_alpha_deg: " << x.plane_alpha_deg << "\n  plane_beta_deg: " << x.plane_beta_deg
    << "\n";
  if (x.energies == 2) {
    const SandwichDetector& d = x.sandwich;
    o << "  energies: 2\n  sandwich: {kvp: " << d.kvp
      << ", tube_filter_al_mm: " << d.tube_filter_al_mm << ", front_csi_mm: " << d.front_csi_mm
      << ", filter_cu_mm: " << d.filter_cu_mm << ", back_csi_mm: " << d.back_csi_mm
      << ", low_photons: " << d.low_photons << "}\n";
    if (x.has_dual_energy) {
      const kernel::DualEnergyK& k = x.dual_energy;
      // Every bit of the fit: read back, a pixel's decomposition is the one calibrated.
      o.precision(17);
      o << "  dual_energy:\n    low: ";
      list(k.low, DE_TERMS);
      o << "\n    high: ";
      list(k.high, DE_TERMS);
      o << "\n    minv: ";
      list(k.minv, 9);
      o << "\n    basis: ";
      list(k.basis, 6);
      o << "\n    var_a: " << k.var_a << "\n    var_b: " << k.var_b
        << "\n    gain_low: " << k.gain_low << "\n    gain_high: " << k.gain_high
        << "\n    var_e_low: " << k.var_e_low << "\n    var_e_high: " << k.var_e_high
        << "\n    var_t: " << k.var_t << "\n";
      if (!x.dual_energy_fitted_on.empty())
        o << "    fitted_on: " << yaml_string(x.dual_energy_fitted_on) << "\n";
    }
  }
  return o.str();
}

}  // namespace rangex
