#include "core/learned_detection.h"

#include <algorithm>

#include "core/error.h"

namespace rangex {

const char* statistic_name(int stat) {
  static const char* kNames[kStatistics] = {"round", "needle", "air"};
  return stat >= 0 && stat < kStatistics ? kNames[stat] : "?";
}

int parse_statistic(const std::string& name) {
  for (int s = 0; s < kStatistics; ++s)
    if (name == statistic_name(s)) return s;
  fail("unknown detection statistic '", name, "' (round, needle or air)");
}

const std::vector<double>& default_band_edges_mm() {
  // Up to 35 mm of meat: a fillet's thickest parts are its roughest (texture grows with the
  // meat), and one band over 25 mm would hold the 25-30 mm meat to the 35-40 mm threshold.
  static const std::vector<double> kEdges = {0, 5, 10, 15, 20, 25, 30, 35, 1000};
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

}  // namespace rangex
