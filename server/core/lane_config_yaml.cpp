// A lane's YAML: its sections read over a base lane (the plant's lanes, a lane's calibration
// file; the xray and inspection sections in xray_yaml.cpp and inspection_yaml.cpp), its
// sensors, and its calibration written back at full precision.
#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

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

void read_laser_plane(const ConfigNode& n, LaserPlane& L) {
  n.only_keys({"normal", "offset_mm"});
  if (n.has("normal")) {
    const auto v = n.at("normal").numbers(3);
    const Vec3 nv{v[0], v[1], v[2]};
    if (nv.norm() < 1e-9) n.at("normal").bad("must not be the zero vector");
    L.normal = nv.normalized();
  }
  n.get("offset_mm", L.offset_mm);
}

void read_stripe(const ConfigNode& n, StripeParams& p) {
  n.only_keys({"method", "min_peak", "threshold_rel", "max_width"});
  if (n.has("method")) {
    try {
      p.method = parse_stripe_method(n.at("method").str());
    } catch (const Error& e) {
      n.at("method").bad(e.what());
    }
  }
  n.positive("min_peak", p.min_peak);
  if (p.min_peak > 255) n.at("min_peak").bad("must be <= 255 for Mono8 frames");
  n.get("threshold_rel", p.threshold_rel);
  if (!(p.threshold_rel > 0 && p.threshold_rel < 1)) n.at("threshold_rel").bad("must be in (0, 1)");
  n.positive("max_width", p.max_width);
}

void read_fusion(const ConfigNode& n, FusionParams& f) {
  n.only_keys({"grid_pitch_mm", "grid_x0_mm", "grid_samples", "agree_tol_mm", "max_gap_mm",
               "max_column_step_mm"});
  n.positive("grid_pitch_mm", f.grid_pitch_mm);
  n.get("grid_x0_mm", f.grid_x0_mm);
  n.positive("grid_samples", f.grid_samples);
  n.positive("agree_tol_mm", f.agree_tol_mm);
  n.get("max_gap_mm", f.max_gap_mm);
  if (f.max_gap_mm < 0) n.at("max_gap_mm").bad("must be >= 0");
  n.positive("max_column_step_mm", f.max_column_step_mm);
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
  if (auto n = section("laser_plane")) read_laser_plane(*n, c.laser);
  if (auto n = section("xray")) read_xray(*n, c.xray);
  if (auto n = section("stripe")) read_stripe(*n, c.stripe);
  if (auto n = section("rectify")) {
    n->only_keys({"lut_step_px"});
    n->positive("lut_step_px", c.lut_step_px);
    if (c.lut_step_px > 64) n->at("lut_step_px").bad("must be <= 64");
  }
  if (auto n = section("fusion")) read_fusion(*n, c.fusion);
  if (auto n = section("inspection")) read_inspection(*n, c.inspection);
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
