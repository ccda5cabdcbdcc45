// The records the store keeps and the record chain hashes: a fillet's decision with its
// fragments, and an audit entry. Their own header, so that the chain and the store each
// include them and not each other.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace rangex {

struct StoredFragment {
  std::string kind;
  double x_mm, y_mm, area_mm2, peak_z, attenuation_mm2;
  double meat_mm = 0;                          // peak excess attenuation in mm of the fillet's meat
  int row0 = 0, row1 = 0, col0 = 0, col1 = 0;  // bounding box in the fillet's images
  double bone_mg = 0;                          // dual energy: bone-equivalent mass; 0 at one energy
};

struct StoredFillet {
  int64_t uid = 0;
  int lane = 0;
  int64_t lane_fillet = 0, first_encoder = 0;
  int rows = 0;
  std::string decision, reason, calibration_id;
  double beta0 = 0, beta1 = 0, beta2 = 0, resid_mean_dn = 0, resid_std_dn = 0, belt_y0_mm = 0;
  int64_t decided_ns = 0;
  std::vector<StoredFragment> fragments;
};

struct AuditEntry {
  int64_t ts_ns = 0;
  std::string who, what, detail;
};

}  // namespace rangex
