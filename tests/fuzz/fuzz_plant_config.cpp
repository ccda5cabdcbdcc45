// plant.yaml and calibration sets as an integrator (or a corrupted file) might write them:
// either refused with rangex::Error naming the key, or read into a plant whose lanes
// round-trip through the calibration YAML the server stores. Anything else (another
// exception escaping, a crash, undefined behaviour) is a finding.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "core/error.h"
#include "core/plant_config.h"

using namespace rangex;

namespace {
// Two YAML texts equal but for numbers, which agree to 1 nm or 1e-9 relative (a camera's
// centre is kept as a rotation and translation, so it reads back within rounding).
bool same_but_rounding(const std::string& a, const std::string& b) {
  const char *p = a.c_str(), *q = b.c_str();
  while (*p && *q) {
    char *pe = nullptr, *qe = nullptr;
    const double x = std::strtod(p, &pe), y = std::strtod(q, &qe);
    if (pe != p && qe != q) {
      // Text inside strings parses too ("nan", "inf"): equal is equal.
      const bool same = x == y || (std::isnan(x) && std::isnan(y));
      if (!same && !(std::fabs(x - y) <= 1e-6 + 1e-9 * std::fabs(x))) return false;
      p = pe, q = qe;
    } else if (*p++ != *q++) {
      return false;
    }
  }
  return *p == *q;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const PlantConfig p = parse_plant_config(text, "fuzz.yaml");
    if (p.lanes.empty()) std::abort();  // a plant without lanes must be refused
    for (const LaneConfig& l : p.lanes) {
      // What the store keeps for a lane reads back to the same calibration.
      const std::string yaml = lane_calibration_yaml(l);
      const LaneConfig again = apply_lane_calibration(l, yaml, "round trip");
      if (!same_but_rounding(lane_calibration_yaml(again), yaml)) std::abort();
      // Learned settings, as the server stores a version, read back to the same.
      if (l.inspection.learned.active()) {
        const std::string learned = learned_detection_yaml(l.inspection.learned);
        const LearnedDetection back = parse_learned_detection(learned, "round trip");
        if (!same_but_rounding(learned_detection_yaml(back), learned)) std::abort();
      }
    }
  } catch (const Error&) {
  }
  try {
    // The same text as a calibration set uploaded for a lane of the shipped rig.
    apply_lane_calibration(default_plant_config(1).lanes[0], text, "fuzz calibration");
  } catch (const Error&) {
  }
  return 0;
}
