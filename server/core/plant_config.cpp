#include "core/plant_config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

#include "core/error.h"
#include "core/size_limits.h"

namespace rangex {

namespace {

// A YAML node with the dotted path that led to it, so that every error names its key.
struct Node {
  YAML::Node node;
  std::string path;
  const std::string* origin;

  [[noreturn]] void bad(const std::string& why) const {
    if (path.empty()) fail(*origin, ": ", why);
    fail(*origin, ": ", path, ": ", why);
  }

  bool has(const char* key) const { return node.IsMap() && node[key]; }
  Node at(const std::string& key) const {
    return {node[key], path.empty() ? key : path + "." + key, origin};
  }
  Node item(size_t i) const { return {node[i], path + "[" + std::to_string(i) + "]", origin}; }

  void only_keys(std::initializer_list<const char*> keys) const {
    if (!node.IsMap()) bad("expected a mapping");
    std::set<std::string> ok(keys.begin(), keys.end()), seen;
    for (const auto& kv : node) {
      // A list or mapping as a key (found by fuzzing) would escape as yaml-cpp's exception.
      if (!kv.first.IsScalar()) bad("has a key that is not a plain name");
      const auto k = kv.first.as<std::string>();
      // YAML parsers keep one of two equal keys silently; a setting written twice is refused.
      if (!seen.insert(k).second) bad("duplicate key '" + k + "'");
      if (!ok.count(k)) {
        std::string list;
        for (const auto& s : ok) list += (list.empty() ? "" : ", ") + s;
        bad("unknown key '" + k + "' (expected: " + list + ")");
      }
    }
  }

  double num() const {
    double v;
    try {
      v = node.as<double>();
    } catch (const YAML::Exception&) {
      bad("expected a number");
    }
    if (!std::isfinite(v)) bad("must be finite");
    return v;
  }
  int integer() const {
    try {
      return node.as<int>();
    } catch (const YAML::Exception&) {
      bad("expected an integer");
    }
  }
  bool boolean() const {
    try {
      return node.as<bool>();
    } catch (const YAML::Exception&) {
      bad("expected true or false");
    }
  }
  std::string str() const {
    if (!node.IsScalar()) bad("expected a string");
    return node.as<std::string>();
  }
  std::vector<double> numbers(size_t n) const {
    if (!node.IsSequence() || node.size() != n)
      bad("expected a list of " + std::to_string(n) + " numbers");
    std::vector<double> v;
    for (size_t i = 0; i < n; ++i) v.push_back(item(i).num());
    return v;
  }

  // Optional scalar members; absent keys keep the default already in `out`.
  void get(const char* key, double& out) const {
    if (has(key)) out = at(key).num();
  }
  void get(const char* key, int& out) const {
    if (has(key)) out = at(key).integer();
  }
  void get(const char* key, std::string& out) const {
    if (has(key)) out = at(key).str();
  }
  void get(const char* key, bool& out) const {
    if (has(key)) out = at(key).boolean();
  }
  void positive(const char* key, double& out) const {
    get(key, out);
    if (!(out > 0)) at(key).bad("must be > 0");
  }
  void positive(const char* key, int& out) const {
    get(key, out);
    if (out <= 0) at(key).bad("must be > 0");
  }
};

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

void read_camera(const Node& n, LaneCamera& cam, int w, int h) {
  n.only_keys({"name", "intrinsics", "distortion", "rotation", "center_mm", "scatter"});
  n.get("name", cam.name);
  Intrinsics k = cam.model.intrinsics();
  Distortion d = cam.model.distortion();
  Mat3 R = cam.model.rotation();
  Vec3 c = cam.model.center();
  if (n.has("intrinsics")) {
    const Node in = n.at("intrinsics");
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
    const Node s = n.at("scatter");
    s.only_keys({"k1", "k2", "k2_offset", "fitted_on"});
    if (s.has("fitted_on")) cam.scatter_fitted_on = s.at("fitted_on").str();
    s.get("k1", cam.scatter.k1);
    s.get("k2", cam.scatter.k2);
    s.get("k2_offset", cam.scatter.k2_offset);
  }
  cam.model = CameraModel(k, d, R, (R * c) * -1.0, w, h);
}

std::vector<double> number_list(const Node& n, size_t expect) {
  if (!n.node.IsSequence()) n.bad("expected a list of numbers");
  return n.numbers(expect ? expect : n.node.size());
}

// xray.dual_energy (rangexctl calib dual-energy writes it): the wedge's fit as the kernels
// read it (kernels/shared/dual_energy.h).
void read_dual_energy(const Node& n, FanBeam& x) {
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

// `spread: thickness | fillet` (inspection.spread, and what learned settings were learned
// with): whether the statistics' spread is measured by thickness.
bool read_spread(const Node& n) {
  const std::string v = n.str();
  if (v != "thickness" && v != "fillet")
    n.bad("must be thickness (by thickness across the fillet) or fillet (one per fillet)");
  return v == "thickness";
}

// A kernel bank's lists: each kernel's spread, its window (whole pixels within 1..radius)
// and its taps, a full window each.
std::vector<double> read_spreads(const Node& n, size_t m) {
  std::vector<double> v = number_list(n, m);
  for (double x : v)
    if (!(x > 0 && x < 1e6)) n.bad("must be positive");
  return v;
}

std::vector<int> read_radii(const Node& n, size_t m, int radius) {
  std::vector<int> out;
  for (double r : number_list(n, m)) {
    if (!(r >= 1 && r <= radius && r == std::floor(r)))
      n.bad("must be whole pixels within 1.." + std::to_string(radius) + " (radius)");
    out.push_back(int(r));
  }
  return out;
}

std::vector<std::vector<double>> read_taps(const Node& t, const std::vector<int>& radii) {
  std::vector<std::vector<double>> out;
  for (size_t i = 0; i < radii.size(); ++i) {
    const size_t w = size_t(2 * radii[i] + 1);
    out.push_back(number_list(t.item(i), w * w));
    for (double h : out.back())
      if (!std::isfinite(h)) t.item(i).bad("taps must be finite");
  }
  return out;
}

// inspection.learned.matched.needles: the whitened needle kernels, one per diameter, length
// and direction, within the bank's radius. One diameter for all (`diameter_mm`, as every
// learning wrote before a bank of widths) or one per kernel (`diameters_mm`).
void read_needles(const Node& n, int radius, MatchedKernels& k) {
  n.only_keys(
      {"diameter_mm", "diameters_mm", "lengths_mm", "angles_deg", "radii", "spreads", "taps"});
  for (const char* key : {"lengths_mm", "angles_deg", "radii", "spreads", "taps"})
    if (!n.has(key))
      n.bad(
          "expected diameter_mm (or diameters_mm), lengths_mm, angles_deg, radii, spreads and "
          "taps");
  if (n.has("diameter_mm") == n.has("diameters_mm"))
    n.bad("expected one of diameter_mm (one for all) and diameters_mm (one per kernel)");
  k.needle_lengths_mm = number_list(n.at("lengths_mm"), 0);
  const size_t m = k.needle_lengths_mm.size();
  if (m == 0) n.at("lengths_mm").bad("expected one length per kernel");
  const char* dkey = n.has("diameter_mm") ? "diameter_mm" : "diameters_mm";
  k.needle_diameters_mm = n.has("diameter_mm") ? std::vector<double>(m, n.at("diameter_mm").num())
                                               : number_list(n.at("diameters_mm"), m);
  for (double d : k.needle_diameters_mm)
    if (!(d >= 0.2 && d <= 2)) n.at(dkey).bad("must be within 0.2..2 mm");
  k.needle_angles_deg = number_list(n.at("angles_deg"), m);
  for (double a : k.needle_angles_deg)
    if (!(a >= 0 && a < 180)) n.at("angles_deg").bad("must be within [0, 180) degrees");
  k.needle_spreads = read_spreads(n.at("spreads"), m);
  k.needle_radii = read_radii(n.at("radii"), m, radius);
  const Node t = n.at("taps");
  if (!t.node.IsSequence() || t.node.size() != m) t.bad("expected one list of taps per kernel");
  k.needle_taps = read_taps(t, k.needle_radii);
}

// inspection.learned.matched: the whitened round kernels, a full window each.
void read_matched(const Node& n, MatchedKernels& k) {
  n.only_keys({"radius", "radii", "clip", "enclosure_px", "void_level", "sizes_mm", "spreads",
               "taps", "needles"});
  if (!n.has("radius") || !n.has("sizes_mm") || !n.has("spreads") || !n.has("taps"))
    n.bad("expected radius, sizes_mm, spreads and taps");
  int radius = 0;
  n.get("radius", radius);
  if (radius < 1 || radius > 8) n.at("radius").bad("must be within 1..8 pixels");
  n.get("clip", k.clip);
  if (!(k.clip > 0 && k.clip <= 100)) n.at("clip").bad("must be within (0, 100] spreads");
  n.get("enclosure_px", k.enclosure_px);
  if (k.enclosure_px < 0 || k.enclosure_px > 16)
    n.at("enclosure_px").bad("must be within 0..16 pixels (0: the clip alone)");
  n.get("void_level", k.void_level);
  if (!(k.void_level == 0 || (k.void_level >= k.clip && k.void_level <= 1000)))
    n.at("void_level").bad("must be 0 (no voids) or within clip..1000 spreads");
  k.sizes_mm = number_list(n.at("sizes_mm"), 0);
  k.spreads = read_spreads(n.at("spreads"), k.sizes_mm.size());
  const Node t = n.at("taps");
  if (!t.node.IsSequence() || t.node.size() != k.sizes_mm.size() || k.sizes_mm.empty())
    t.bad("expected one list of taps per size in sizes_mm");
  // Each kernel's window (radii; a file without them has one window, radius, for all).
  k.radii = n.has("radii") ? read_radii(n.at("radii"), k.sizes_mm.size(), radius)
                           : std::vector<int>(k.sizes_mm.size(), radius);
  k.taps = read_taps(t, k.radii);
  if (n.has("needles")) read_needles(n.at("needles"), radius, k);
}

// inspection.learned (rangexctl learn writes it): every list matches the bands, the
// thresholds are finite and the model's scale is a scale.
void read_learned(const Node& n, LearnedDetection& L) {
  n.only_keys({"version", "learned_on", "target_frr", "confidence", "fillets", "band_edges_mm",
               "round", "needle", "air", "sensitivity", "spread", "rim_walls", "matched"});
  if (n.has("matched")) read_matched(n.at("matched"), L.matched);
  if (n.has("spread")) L.spread_by_thickness = read_spread(n.at("spread"));
  n.get("rim_walls", L.rim_walls);
  if (n.has("sensitivity")) {
    const Node s = n.at("sensitivity");
    if (!s.node.IsSequence()) s.bad("expected a list of strings");
    for (size_t i = 0; i < s.node.size(); ++i) L.sensitivity.push_back(s.item(i).str());
  }
  n.get("version", L.version);
  n.get("learned_on", L.learned_on);
  n.get("target_frr", L.target_frr);
  if (!(L.target_frr > 0 && L.target_frr < 0.5)) n.at("target_frr").bad("must be in (0, 0.5)");
  n.get("confidence", L.confidence);
  if (!(L.confidence >= 0.5 && L.confidence < 1)) n.at("confidence").bad("must be in [0.5, 1)");
  n.get("fillets", L.fillets);
  if (!n.has("band_edges_mm")) n.bad("missing key 'band_edges_mm'");
  L.band_edges_mm = number_list(n.at("band_edges_mm"), 0);
  if (L.band_edges_mm.size() < 2 || L.band_edges_mm.size() > 33)
    n.at("band_edges_mm").bad("expected 2 to 33 band edges");
  for (size_t i = 1; i < L.band_edges_mm.size(); ++i)
    if (!(L.band_edges_mm[i] > L.band_edges_mm[i - 1])) n.at("band_edges_mm").bad("must increase");
  const size_t bands = L.band_edges_mm.size() - 1;
  for (int s = 0; s < kStatistics; ++s) {
    const char* name = statistic_name(s);
    if (!n.has(name)) n.bad(std::string("missing key '") + name + "'");
    const Node st = n.at(name);
    st.only_keys({"thresholds", "band_fraction", "band_pixels", "band_thickness_mm", "model",
                  "tail_from", "whole_model"});
    LearnedStatistic& ls = L.stats[size_t(s)];
    if (!st.has("thresholds")) st.bad("missing key 'thresholds'");
    ls.thresholds = number_list(st.at("thresholds"), bands);
    // Positive and finite; not bounded tighter: learning reports what the product's extremes
    // are (the air statistic at steep walls reached thousands), and must read back what it
    // wrote.
    for (double t : ls.thresholds)
      if (!(t > 0 && t < kMaxLearnedThreshold)) st.at("thresholds").bad("must be within (0, 1e6)");
    if (st.has("band_fraction")) ls.band_fraction = number_list(st.at("band_fraction"), bands);
    if (st.has("band_pixels")) ls.band_pixels = number_list(st.at("band_pixels"), bands);
    if (st.has("band_thickness_mm"))
      ls.band_thickness_mm = number_list(st.at("band_thickness_mm"), bands);
    auto read_model = [](const Node& m, GevModel& g) {
      m.only_keys({"m0", "m_logn", "m_t", "s0", "s_t", "xi", "log_n_ref", "t_ref", "k_logn"});
      m.get("m0", g.m0), m.get("m_logn", g.m_logn), m.get("m_t", g.m_t), m.get("s0", g.s0);
      m.get("k_logn", g.k_logn);  // 0 in models learned before (core/gev_model.h)
      if (!(std::abs(g.k_logn) <= 10)) m.at("k_logn").bad("must be within [-10, 10]");
      m.get("s_t", g.s_t), m.get("xi", g.xi), m.get("log_n_ref", g.log_n_ref);
      m.get("t_ref", g.t_ref);
      if (!(g.xi > -1 && g.xi < 1)) m.at("xi").bad("must be within (-1, 1)");
      if (!(std::abs(g.s0) < 20)) m.at("s0").bad("must be within (-20, 20) (a log scale)");
    };
    if (st.has("model")) read_model(st.at("model"), ls.model);
    if (st.has("tail_from")) {
      st.get("tail_from", ls.tail_from);
      if (!(ls.tail_from >= 0 && ls.tail_from < 1)) st.at("tail_from").bad("must be within [0, 1)");
      if (ls.tail_from > 0 && !st.has("whole_model"))
        st.bad("a tail fit (tail_from > 0) needs 'whole_model', the fit that censored it");
    }
    if (st.has("whole_model")) read_model(st.at("whole_model"), ls.whole_model);
  }
}

// Reads one lane from its own node over `c`, falling back section by section to
// lane_defaults.
void read_sources(const Node& n, SensorSources& s) {
  n.only_keys(
      {"cameras", "xray", "trigger", "trigger_line", "offset_y", "exposure_us", "packet_size"});
  if (!n.has("cameras")) n.bad("missing key 'cameras' (two laser cameras)");
  const Node cams = n.at("cameras");
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

void read_plc(const Node& n, PlcConfig& c) {
  n.only_keys({"address", "unit_id", "heartbeat_register", "lane_state_base", "ring_head_register",
               "ring_base", "ring_slots", "reject_station_mm", "margin_mm", "heartbeat_ms",
               "timeout_ms"});
  if (!n.has("address")) n.bad("missing key 'address' (host:port of the PLC's Modbus TCP server)");
  n.get("address", c.address);
  const auto colon = c.address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == c.address.size())
    n.at("address").bad("must be host:port (got '" + c.address + "')");
  n.get("unit_id", c.unit_id);
  if (c.unit_id < 0 || c.unit_id > 247) n.at("unit_id").bad("must be 0..247");
  for (const char* k :
       {"heartbeat_register", "lane_state_base", "ring_head_register", "ring_base"}) {
    int v = 0;
    n.get(k, v);
    if (n.has(k) && (v < 0 || v > 65535)) n.at(k).bad("must be a register 0..65535");
  }
  n.get("heartbeat_register", c.heartbeat_register);
  n.get("lane_state_base", c.lane_state_base);
  n.get("ring_head_register", c.ring_head_register);
  n.get("ring_base", c.ring_base);
  n.positive("ring_slots", c.ring_slots);
  if (c.ring_end() > 65536) n.at("ring_slots").bad("the ring runs past register 65535");
  n.positive("reject_station_mm", c.reject_station_mm);
  n.get("margin_mm", c.margin_mm);
  if (c.margin_mm < 0 || c.margin_mm >= c.reject_station_mm)
    n.at("margin_mm").bad("must be >= 0 and less than reject_station_mm");
  n.positive("heartbeat_ms", c.heartbeat_ms);
  n.positive("timeout_ms", c.timeout_ms);
  // The registers rangex writes must not overlap.
  const int lanes_end = c.lane_state_base + 2 * PlcConfig::kMaxLanes;
  auto overlaps = [](int a0, int a1, int b0, int b1) { return a0 < b1 && b0 < a1; };
  if (overlaps(c.ring_base, c.ring_end(), c.lane_state_base, lanes_end) ||
      overlaps(c.ring_base, c.ring_end(), c.heartbeat_register, c.heartbeat_register + 1) ||
      overlaps(c.ring_base, c.ring_end(), c.ring_head_register, c.ring_head_register + 1) ||
      overlaps(c.lane_state_base, lanes_end, c.heartbeat_register, c.heartbeat_register + 1) ||
      overlaps(c.lane_state_base, lanes_end, c.ring_head_register, c.ring_head_register + 1) ||
      c.heartbeat_register == c.ring_head_register)
    n.bad("the heartbeat, lane state (2 x 64 lanes), ring head and ring registers overlap");
}

LaneConfig read_lane(const Node& lane, const Node* defaults, LaneConfig c) {
  auto section = [&](const char* key) -> std::optional<Node> {
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
      const Node d = n->at("sandwich");
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
      const Node d = n->at("matched_needle_diameter_mm");
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

void read_engine(const Node& n, EngineSettings& e) {
  n.only_keys({"queue_lines", "batch_lines", "batch_wait_ms", "inspectors", "dedup_window",
               "auto_reset", "idle_close_s", "stall_s", "exit_after_s", "drain_timeout_s",
               "verify_fraction", "stream_idle_s", "store_reserve_mb"});
  int queue = int(e.queue_lines);
  n.positive("queue_lines", queue);
  if (queue > 1 << 20) n.at("queue_lines").bad("must be <= 1048576");
  e.queue_lines = size_t(queue);
  n.positive("batch_lines", e.batch_lines);
  n.positive("batch_wait_ms", e.batch_wait_ms);
  n.positive("inspectors", e.inspectors);
  if (e.inspectors > 64) n.at("inspectors").bad("must be <= 64");
  n.positive("dedup_window", e.dedup_window);
  if (e.dedup_window > 1 << 24) n.at("dedup_window").bad("must be <= 16777216");
  n.get("auto_reset", e.auto_reset);
  n.positive("idle_close_s", e.idle_close_s);
  n.positive("stall_s", e.stall_s);
  n.get("exit_after_s", e.exit_after_s);
  if (e.exit_after_s < 0) n.at("exit_after_s").bad("must be >= 0 (0: never)");
  n.positive("drain_timeout_s", e.drain_timeout_s);
  n.positive("stream_idle_s", e.stream_idle_s);
  n.get("store_reserve_mb", e.store_reserve_mb);
  if (!(e.store_reserve_mb >= 0)) n.at("store_reserve_mb").bad("must be >= 0 (0: no warning)");
  n.get("verify_fraction", e.verify_fraction);
  if (!(e.verify_fraction >= 0 && e.verify_fraction <= 1))
    n.at("verify_fraction").bad("must be between 0 and 1");
}

Role read_role(const Node& n) {
  const std::string s = n.str();
  const auto r = parse_role(s);
  if (!r || *r == Role::none)
    n.bad("must be one of viewer, operator, engineer, admin (got '" + s + "')");
  return *r;
}

void read_security(const Node& n, SecurityConfig& s) {
  n.only_keys({"tls", "identities", "tokens", "anonymous", "insecure"});
  if (n.has("tls")) {
    const Node t = n.at("tls");
    t.only_keys({"cert", "key", "client_ca"});
    t.get("cert", s.tls_cert);
    t.get("key", s.tls_key);
    t.get("client_ca", s.client_ca);
    if (s.tls_cert.empty() != s.tls_key.empty())
      t.bad("needs both cert and key (the server's certificate chain and its private key)");
    if (!s.client_ca.empty() && s.tls_cert.empty())
      t.bad("client_ca needs the server's own cert and key: client certificates are TLS");
  }
  if (n.has("identities")) {
    const Node ids = n.at("identities");
    if (!ids.node.IsMap()) ids.bad("expected a mapping of certificate common name to role");
    for (const auto& kv : ids.node) {
      if (!kv.first.IsScalar()) ids.bad("has a name that is not a plain string");
      const auto name = kv.first.as<std::string>();
      if (!s.identities.emplace(name, read_role(ids.at(name))).second)
        ids.bad("duplicate identity '" + name + "'");
    }
    if (!s.identities.empty() && s.client_ca.empty())
      ids.bad(
          "names certificate identities but tls.client_ca is not set: no client "
          "certificate could be verified");
  }
  if (n.has("tokens")) {
    const Node list = n.at("tokens");
    if (!list.node.IsSequence()) list.bad("expected a list of {name, role, sha256}");
    std::set<std::string> names, hashes;
    for (size_t i = 0; i < list.node.size(); ++i) {
      const Node t = list.item(i);
      t.only_keys({"name", "role", "sha256"});
      for (const char* k : {"name", "role", "sha256"})
        if (!t.has(k)) t.bad(std::string("missing key '") + k + "'");
      TokenEntry e{t.at("name").str(), read_role(t.at("role")), t.at("sha256").str()};
      if (e.name.empty()) t.at("name").bad("must not be empty");
      const bool hex = e.sha256.size() == 64 &&
                       e.sha256.find_first_not_of("0123456789abcdef") == std::string::npos;
      if (!hex)
        t.at("sha256").bad(
            "must be the token's SHA-256 as 64 lower-case hex digits "
            "(rangexctl token prints it)");
      if (!names.insert(e.name).second) t.at("name").bad("duplicate token name '" + e.name + "'");
      if (!hashes.insert(e.sha256).second) t.at("sha256").bad("the same token is listed twice");
      s.tokens.push_back(std::move(e));
    }
    if (!s.tokens.empty() && !s.tls())
      list.bad(
          "bearer tokens need tls: a token sent in clear can be replayed by anyone on "
          "the path");
  }
  if (n.has("anonymous")) {
    const Node a = n.at("anonymous");
    const auto r = parse_role(a.str());
    if (!r) a.bad("must be one of none, viewer, operator, engineer, admin (got '" + a.str() + "')");
    s.anonymous = *r;
  }
  n.get("insecure", s.insecure);
}

}  // namespace

static YAML::Node load_yaml(const std::string& text, const std::string& origin) {
  check_size(origin, text.size(), kMaxYamlBytes);
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    fail(origin, ": not valid YAML: ", e.what());
  }
}

const LaneConfig& PlantConfig::lane(int id) const {
  for (const auto& l : lanes)
    if (l.id == id) return l;
  fail_not_found("unknown lane ", id, " (plant '", name, "' has ", lanes.size(), " lanes)");
}

PlantConfig parse_plant_config(const std::string& text, const std::string& origin) {
  const YAML::Node root = load_yaml(text, origin);
  const Node top{root, "", &origin};
  top.only_keys({"plant", "server", "security", "retention", "plc", "verification", "lane_defaults",
                 "lanes"});
  PlantConfig p;
  if (top.has("plant")) {
    const Node n = top.at("plant");
    n.only_keys({"name", "calibration_id", "backend", "device", "listen", "http", "storage",
                 "results_db", "server_id", "results_db_retry_max_s"});
    n.get("name", p.name);
    n.get("calibration_id", p.calibration_id);
    n.get("backend", p.backend);
    if (p.backend != "auto" && p.backend != "cpu" && p.backend != "opencl" && p.backend != "vulkan")
      n.at("backend").bad("must be one of auto, cpu, opencl, vulkan (got '" + p.backend + "')");
    n.get("device", p.device);
    n.get("listen", p.listen);
    n.get("http", p.http);
    if (p.http != "off" && p.http.rfind(':') == std::string::npos)
      n.at("http").bad("must be host:port or off (got '" + p.http + "')");
    n.get("storage", p.storage);
    n.get("results_db", p.results_db);
    // A password in plant.yaml is a password every reader of the file has: libpq's password
    // file (PGPASSFILE, ~/.pgpass or passfile=) keeps it apart.
    if (p.results_db.find("password") != std::string::npos ||
        (p.results_db.find("://") != std::string::npos &&
         p.results_db.find('@') != std::string::npos &&
         p.results_db.substr(0, p.results_db.find('@')).find(':', p.results_db.find("://") + 3) !=
             std::string::npos))
      n.at("results_db")
          .bad(
              "holds a password: put it in a password file (PGPASSFILE, ~/.pgpass or "
              "passfile=...)");
    n.get("server_id", p.server_id);
    for (char c : p.server_id)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
        n.at("server_id").bad("'" + p.server_id + "': letters, digits, '-', '_' and '.' only");
    n.get("results_db_retry_max_s", p.results_db_retry_max_s);
    if (!(p.results_db_retry_max_s >= 1 && p.results_db_retry_max_s <= 3600))
      n.at("results_db_retry_max_s").bad("must be within 1..3600 s (the first retry waits 1 s)");
  }
  if (top.has("server")) read_engine(top.at("server"), p.engine);
  if (top.has("security")) read_security(top.at("security"), p.security);
  if (top.has("retention")) {
    const Node n = top.at("retention");
    RetentionSettings& r = p.retention;
    n.only_keys({"days", "images_days", "every_h"});
    n.get("days", r.days);
    if (!(r.days >= 1)) n.at("days").bad("must be >= 1 (records are kept at least a day)");
    r.images_days = r.days;
    n.get("images_days", r.images_days);
    if (!(r.images_days >= 1 && r.images_days <= r.days))
      n.at("images_days").bad("must be between 1 and days (" + std::to_string(r.days) + ")");
    n.positive("every_h", r.every_h);
  }
  if (top.has("plc")) read_plc(top.at("plc"), p.plc);
  if (top.has("verification")) {
    const Node n = top.at("verification");
    n.only_keys({"every_h", "fillets", "tolerance_mm"});
    n.get("every_h", p.verification.every_h);
    if (p.verification.every_h < 0) n.at("every_h").bad("must be >= 0 (0: no schedule)");
    n.positive("fillets", p.verification.fillets);
    n.positive("tolerance_mm", p.verification.tolerance_mm);
  }
  std::optional<Node> defaults;
  if (top.has("lane_defaults")) defaults = top.at("lane_defaults");
  if (!top.has("lanes")) top.bad("missing key 'lanes'");
  const Node lanes = top.at("lanes");
  if (!lanes.node.IsSequence() || lanes.node.size() == 0) lanes.bad("expected a non-empty list");
  std::set<int> seen;
  std::set<std::string> sensors;
  for (size_t i = 0; i < lanes.node.size(); ++i) {
    const Node ln = lanes.item(i);
    ln.only_keys({"id", "server", "frame", "encoder_step_mm", "cameras", "laser_plane", "xray",
                  "stripe", "rectify", "fusion", "inspection", "sources"});
    if (!ln.has("id")) ln.bad("missing key 'id'");
    const int id = ln.at("id").integer();
    if (id < 0) ln.at("id").bad("must be >= 0");
    LaneConfig l = read_lane(ln, defaults ? &*defaults : nullptr, default_lane_config(id));
    // A lane's sensors are its own: never in lane_defaults.
    if (ln.has("sources")) read_sources(ln.at("sources"), l.sources);
    if (!seen.insert(l.id).second)
      lanes.item(i).at("id").bad("duplicate lane id " + std::to_string(l.id));
    for (const std::string& d : l.sources.devices())
      if (!sensors.insert(d).second)
        ln.at("sources").bad("device '" + d + "' already belongs to another lane");
    if (p.plc.enabled() && l.id >= PlcConfig::kMaxLanes)
      ln.at("id").bad("lane ids go up to " + std::to_string(PlcConfig::kMaxLanes - 1) +
                      " with a PLC (its lane state registers)");
    if (ln.has("server")) {
      const std::string server = ln.at("server").str();
      if (server.empty() || server.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQ"
                                                     "RSTUVWXYZ0123456789-_.") != std::string::npos)
        ln.at("server").bad("'" + server + "': a server id (letters, digits, '-', '_' and '.')");
      p.lane_servers[l.id] = server;
    }
    if (!p.lane_servers.empty() && p.lane_servers.size() != i + 1)
      ln.bad("every lane names its server (key 'server') or none does");
    p.lanes.push_back(std::move(l));
  }
  return p;
}

PlantConfig plant_for_server(const PlantConfig& plant, const std::string& server_id) {
  if (plant.lane_servers.empty()) return plant;
  PlantConfig p = plant;
  p.lanes.clear();
  std::set<std::string> named;
  for (const LaneConfig& l : plant.lanes) {
    const std::string& s = plant.lane_servers.at(l.id);
    named.insert(s);
    if (s == server_id) p.lanes.push_back(l);
  }
  if (p.lanes.empty()) {
    std::string list;
    for (const std::string& s : named) list += (list.empty() ? "" : ", ") + s;
    fail("plant '", plant.name, "' assigns no lane to server '", server_id, "' (its lanes name ",
         list, "): start rangexd with --server-id, or set plant.server_id");
  }
  return p;
}

LaneConfig apply_lane_calibration(const LaneConfig& base, const std::string& text,
                                  const std::string& origin) {
  const YAML::Node root = load_yaml(text, origin);
  const Node n{root, "", &origin};
  if (!root.IsMap())
    n.bad(root.IsNull() ? "is empty; expected a mapping with cameras, laser_plane, xray or "
                          "encoder_step_mm"
                        : "expected a mapping with cameras, laser_plane, xray or encoder_step_mm");
  n.only_keys({"cameras", "laser_plane", "xray", "encoder_step_mm"});
  return read_lane(n, nullptr, base);
}

LearnedDetection parse_learned_detection(const std::string& text, const std::string& origin) {
  const YAML::Node root = load_yaml(text, origin);
  LearnedDetection L;
  read_learned(Node{root, "", &origin}, L);
  return L;
}

PlantConfig load_plant_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, ": cannot open plant configuration");
  // Sized before it is read: a huge file is refused without taking its memory.
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(path, ec);
  if (!ec) check_size(path + " (the plant configuration)", size_t(bytes), kMaxPlantConfigBytes);
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_plant_config(ss.str(), path);
}

PlantConfig default_plant_config(int lanes) {
  PlantConfig p;
  for (int i = 0; i < lanes; ++i) p.lanes.push_back(default_lane_config(i));
  return p;
}

namespace {
// A string as a YAML scalar that reads back as itself (found by fuzzing: a camera name or a
// fitted_on note with a quote or a line break was written as is, and the stored calibration
// no longer read back).
std::string yaml_string(const std::string& s) {
  YAML::Emitter e;
  e << YAML::DoubleQuoted << s;
  return e.c_str();
}
}  // namespace

std::string learned_detection_yaml(const LearnedDetection& L) {
  std::ostringstream o;
  o.precision(12);
  auto list = [&o](const auto& v) {
    o << "[";
    for (size_t i = 0; i < v.size(); ++i) o << (i ? ", " : "") << v[i];
    o << "]";
  };
  o << "version: " << yaml_string(L.version) << "\nlearned_on: " << yaml_string(L.learned_on)
    << "\ntarget_frr: " << L.target_frr << "\nconfidence: " << L.confidence
    << "\nfillets: " << L.fillets
    << "\nspread: " << (L.spread_by_thickness ? "thickness" : "fillet")
    << "\nrim_walls: " << (L.rim_walls ? "true" : "false") << "\nband_edges_mm: ";
  list(L.band_edges_mm);
  o << "\nsensitivity: [";
  for (size_t i = 0; i < L.sensitivity.size(); ++i)
    o << (i ? ", " : "") << yaml_string(L.sensitivity[i]);
  o << "]";
  if (!L.matched.empty()) {
    o << "\nmatched:\n  radius: " << L.matched.radius() << "\n  clip: " << L.matched.clip;
    if (L.matched.enclosure_px > 0) o << "\n  enclosure_px: " << L.matched.enclosure_px;
    if (L.matched.void_level > 0) o << "\n  void_level: " << L.matched.void_level;
    o << "\n  sizes_mm: ";
    list(L.matched.sizes_mm);
    o << "\n  radii: ";
    list(L.matched.radii);
    o << "\n  spreads: ";
    list(L.matched.spreads);
    o << "\n  taps:";
    for (const std::vector<double>& t : L.matched.taps) {
      o << "\n    - ";
      list(t);
    }
    const MatchedKernels& k = L.matched;
    if (k.has_needles()) {
      // One diameter for all as before a bank of widths, else one per kernel.
      const auto& d = k.needle_diameters_mm;
      if (std::all_of(d.begin(), d.end(), [&](double x) { return x == d.front(); })) {
        o << "\n  needles:\n    diameter_mm: " << d.front();
      } else {
        o << "\n  needles:\n    diameters_mm: ";
        list(d);
      }
      o << "\n    lengths_mm: ";
      list(k.needle_lengths_mm);
      o << "\n    angles_deg: ";
      list(k.needle_angles_deg);
      o << "\n    radii: ";
      list(k.needle_radii);
      o << "\n    spreads: ";
      list(k.needle_spreads);
      o << "\n    taps:";
      for (const std::vector<double>& t : k.needle_taps) {
        o << "\n      - ";
        list(t);
      }
    }
  }
  for (int s = 0; s < kStatistics; ++s) {
    const LearnedStatistic& ls = L.stats[size_t(s)];
    o << "\n" << statistic_name(s) << ":\n  thresholds: ";
    list(ls.thresholds);
    o << "\n  band_fraction: ";
    list(ls.band_fraction);
    o << "\n  band_pixels: ";
    list(ls.band_pixels);
    o << "\n  band_thickness_mm: ";
    list(ls.band_thickness_mm);
    auto model = [&o](const char* key, const GevModel& g) {
      o << "\n  " << key << ": {m0: " << g.m0 << ", m_logn: " << g.m_logn << ", m_t: " << g.m_t
        << ", s0: " << g.s0 << ", s_t: " << g.s_t << ", xi: " << g.xi
        << ", log_n_ref: " << g.log_n_ref << ", t_ref: " << g.t_ref << ", k_logn: " << g.k_logn
        << "}";
    };
    model("model", ls.model);
    if (ls.tail_from > 0) {
      o << "\n  tail_from: " << ls.tail_from;
      model("whole_model", ls.whole_model);
    }
  }
  o << "\n";
  return o.str();
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
