#include "core/calibration_report.h"

#include <yaml-cpp/yaml.h>

namespace rangex {

ReportStatus check_calibration_report(const std::string& json) {
  ReportStatus s;
  if (json.find_first_not_of(" \t\r\n") == std::string::npos) {
    s.why = "the calibration has no report";
    return s;
  }
  s.present = true;
  try {
    // JSON is YAML's flow style: yaml-cpp reads it.
    const YAML::Node doc = YAML::Load(json);
    const YAML::Node reports = doc["reports"];
    if (!reports || !reports.IsSequence() || reports.size() == 0) {
      s.why = "the report holds no solver result";
      return s;
    }
    for (const auto& r : reports) {
      if (r["passed"] && r["passed"].as<bool>()) continue;
      s.why = "the " + r["solver"].as<std::string>("?") + " solve of " +
              r["subject"].as<std::string>("?") + " failed";
      if (r["failures"] && r["failures"].IsSequence() && r["failures"].size() > 0)
        s.why += ": " + r["failures"][0].as<std::string>("");
      return s;
    }
    s.passed = true;
  } catch (const YAML::Exception& e) {
    s.why = std::string("the report cannot be read: ") + e.what();
  }
  return s;
}

}  // namespace rangex
