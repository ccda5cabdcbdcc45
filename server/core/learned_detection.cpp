#include "core/learned_detection.h"

#include <algorithm>
#include <sstream>

namespace rangex {

const char* statistic_name(int stat) {
  static const char* kNames[kStatistics] = {"round", "needle", "air"};
  return stat >= 0 && stat < kStatistics ? kNames[stat] : "?";
}

const std::vector<double>& default_band_edges_mm() {
  static const std::vector<double> kEdges = {0, 5, 10, 15, 20, 25, 1000};
  return kEdges;
}

int band_index(const std::vector<double>& edges, double t) {
  const int bands = int(edges.size()) - 1;
  if (bands <= 0) return 0;
  const auto it = std::upper_bound(edges.begin(), edges.end(), t);
  return std::clamp(int(it - edges.begin()) - 1, 0, bands - 1);
}

int LearnedDetection::band_of(double t) const {
  return band_index(band_edges_mm, t);
}

double LearnedDetection::threshold(int stat, double t) const {
  return stats[size_t(stat)].thresholds[size_t(band_of(t))];
}

std::string learned_detection_yaml(const LearnedDetection& L) {
  std::ostringstream o;
  o.precision(12);
  auto list = [&o](const std::vector<double>& v) {
    o << "[";
    for (size_t i = 0; i < v.size(); ++i) o << (i ? ", " : "") << v[i];
    o << "]";
  };
  // Strings double-quoted with escapes, so that any name reads back as itself.
  auto quoted = [&o](const std::string& s) {
    o << '"';
    for (char c : s) {
      if (c == '"' || c == '\\')
        o << '\\' << c;
      else if (c == '\n')
        o << "\\n";
      else if (static_cast<unsigned char>(c) < 0x20)
        o << ' ';
      else
        o << c;
    }
    o << '"';
  };
  o << "version: ";
  quoted(L.version);
  o << "\nlearned_on: ";
  quoted(L.learned_on);
  o << "\ntarget_frr: " << L.target_frr << "\nconfidence: " << L.confidence
    << "\nfillets: " << L.fillets
    << "\nspread: " << (L.spread_by_thickness ? "thickness" : "fillet") << "\nband_edges_mm: ";
  list(L.band_edges_mm);
  o << "\nsensitivity: [";
  for (size_t i = 0; i < L.sensitivity.size(); ++i) {
    o << (i ? ", " : "");
    quoted(L.sensitivity[i]);
  }
  o << "]";
  for (int s = 0; s < kStatistics; ++s) {
    const LearnedStatistic& ls = L.stats[size_t(s)];
    const GevModel& g = ls.model;
    o << "\n" << statistic_name(s) << ":\n  thresholds: ";
    list(ls.thresholds);
    o << "\n  band_fraction: ";
    list(ls.band_fraction);
    o << "\n  band_pixels: ";
    list(ls.band_pixels);
    o << "\n  band_thickness_mm: ";
    list(ls.band_thickness_mm);
    o << "\n  model: {m0: " << g.m0 << ", m_logn: " << g.m_logn << ", m_t: " << g.m_t
      << ", s0: " << g.s0 << ", s_t: " << g.s_t << ", xi: " << g.xi
      << ", log_n_ref: " << g.log_n_ref << ", t_ref: " << g.t_ref << "}";
  }
  o << "\n";
  return o.str();
}

}  // namespace rangex
