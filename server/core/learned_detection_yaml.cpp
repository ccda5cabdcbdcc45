// The learned detection's YAML (inspection.learned): read with every list and bound checked,
// and written back so that it reads as itself.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/config_yaml.h"

namespace rangex {

// `spread: thickness | fillet` (inspection.spread, and what learned settings were learned
// with): whether the statistics' spread is measured by thickness.
bool read_spread(const ConfigNode& n) {
  const std::string v = n.str();
  if (v != "thickness" && v != "fillet")
    n.bad("must be thickness (by thickness across the fillet) or fillet (one per fillet)");
  return v == "thickness";
}

namespace {

// A kernel bank's lists: each kernel's spread, its window (whole pixels within 1..radius)
// and its taps, a full window each.
std::vector<double> read_spreads(const ConfigNode& n, size_t m) {
  std::vector<double> v = number_list(n, m);
  for (double x : v)
    if (!(x > 0 && x < 1e6)) n.bad("must be positive");
  return v;
}

std::vector<int> read_radii(const ConfigNode& n, size_t m, int radius) {
  std::vector<int> out;
  for (double r : number_list(n, m)) {
    if (!(r >= 1 && r <= radius && r == std::floor(r)))
      n.bad("must be whole pixels within 1.." + std::to_string(radius) + " (radius)");
    out.push_back(int(r));
  }
  return out;
}

std::vector<std::vector<double>> read_taps(const ConfigNode& t, const std::vector<int>& radii) {
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
void read_needles(const ConfigNode& n, int radius, MatchedKernels& k) {
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
  const ConfigNode t = n.at("taps");
  if (!t.node.IsSequence() || t.node.size() != m) t.bad("expected one list of taps per kernel");
  k.needle_taps = read_taps(t, k.needle_radii);
}

// inspection.learned.matched: the whitened round kernels, a full window each.
void read_matched(const ConfigNode& n, MatchedKernels& k) {
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
  const ConfigNode t = n.at("taps");
  if (!t.node.IsSequence() || t.node.size() != k.sizes_mm.size() || k.sizes_mm.empty())
    t.bad("expected one list of taps per size in sizes_mm");
  // Each kernel's window (radii; a file without them has one window, radius, for all).
  k.radii = n.has("radii") ? read_radii(n.at("radii"), k.sizes_mm.size(), radius)
                           : std::vector<int>(k.sizes_mm.size(), radius);
  k.taps = read_taps(t, k.radii);
  if (n.has("needles")) read_needles(n.at("needles"), radius, k);
}

}  // namespace

// inspection.learned (rangexctl learn writes it): every list matches the bands, the
// thresholds are finite and the model's scale is a scale.
void read_learned(const ConfigNode& n, LearnedDetection& L) {
  n.only_keys({"version", "learned_on", "target_frr", "confidence", "fillets", "band_edges_mm",
               "round", "needle", "air", "sensitivity", "spread", "rim_walls", "matched"});
  if (n.has("matched")) read_matched(n.at("matched"), L.matched);
  if (n.has("spread")) L.spread_by_thickness = read_spread(n.at("spread"));
  n.get("rim_walls", L.rim_walls);
  if (n.has("sensitivity")) {
    const ConfigNode s = n.at("sensitivity");
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
    const ConfigNode st = n.at(name);
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
    auto read_model = [](const ConfigNode& m, GevModel& g) {
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

LearnedDetection parse_learned_detection(const std::string& text, const std::string& origin) {
  const YAML::Node root = load_yaml(text, origin);
  LearnedDetection L;
  read_learned(ConfigNode{root, "", &origin}, L);
  return L;
}

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

}  // namespace rangex
