// Per-fillet results as CSV tables (fillets.csv, fragments.csv and baseline_*.csv beside
// them), written by `rangexctl process` and read back by `rangexctl eval`.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "pipeline/inspection.h"

namespace rangex {

struct FilletRecord {
  int lane = 0;
  int64_t fillet = 0;
  int64_t first_line = 0;
  int rows = 0;
  double y0_mm = 0, y1_mm = 0;  // belt positions covered
  double x0_mm = 0, x1_mm = 0;  // across the belt (detector)
  std::string decision;
  double beta0 = 0, beta1 = 0, scale = 0;
  int iterations = 0;
  bool converged = false;
  int pixels = 0;
  double resid_mean_dn = 0, resid_std_dn = 0;
  int fragments = 0, air_pockets = 0;
  std::string reason;
};

struct FragmentRecord {
  int lane = 0;
  int64_t fillet = 0;
  std::string kind;  // bone | air
  double x_mm = 0, y_mm = 0, area_mm2 = 0, peak_z = 0, attenuation_mm2 = 0;
  double meat_mm = 0;  // excess attenuation at its peak, in mm of the fillet's meat
  double bone_mg = 0;  // dual energy: bone-equivalent mass (0 at one energy)
};

// One of a fillet's detection extremes per thickness band (FilletResult::extremes): what
// the learning fits and the drift monitor follows.
struct ExtremeRecord {
  int lane = 0;
  int64_t fillet = 0;
  BandExtreme extreme;
};

struct RecordSet {
  std::vector<FilletRecord> fillets;
  std::vector<FragmentRecord> fragments;
  std::vector<ExtremeRecord> extremes;
  void add(const FilletResult& r);
};

// Writes <dir>/<prefix>fillets.csv, <prefix>fragments.csv and <prefix>extremes.csv (read back
// when present: outputs written before it read with no extremes).
void write_records(const std::string& dir, const std::string& prefix, const RecordSet& s);
RecordSet read_records(const std::string& dir, const std::string& prefix);
std::string fillets_json(const RecordSet& s);

}  // namespace rangex
