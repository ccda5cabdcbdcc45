#include "calib/solve_report.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace rangex {

namespace {

std::string quote(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    if (c == '\n') {
      o += "\\n";
      continue;
    }
    o += c;
  }
  return o + "\"";
}

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

}  // namespace

std::string SolveReport::json() const {
  std::ostringstream o;
  o << "{\"solver\": " << quote(solver) << ", \"subject\": " << quote(subject)
    << ", \"passed\": " << (passed ? "true" : "false") << ",\n  \"parameters\": [";
  for (size_t i = 0; i < parameters.size(); ++i) {
    const Estimate& e = parameters[i];
    o << (i ? ",\n    " : "\n    ") << "{\"name\": " << quote(e.name)
      << ", \"value\": " << number(e.value) << ", \"std\": " << number(e.stddev)
      << ", \"unit\": " << quote(e.unit) << "}";
  }
  o << "],\n  \"figures\": {";
  for (size_t i = 0; i < figures.size(); ++i)
    o << (i ? ", " : "") << quote(figures[i].first) << ": " << number(figures[i].second);
  o << "},\n  \"warnings\": [";
  for (size_t i = 0; i < warnings.size(); ++i) o << (i ? ", " : "") << quote(warnings[i]);
  o << "],\n  \"failures\": [";
  for (size_t i = 0; i < failures.size(); ++i) o << (i ? ", " : "") << quote(failures[i]);
  o << "]}";
  return o.str();
}

std::string reports_json(const std::vector<SolveReport>& reports) {
  std::string o = "{\"reports\": [\n";
  for (size_t i = 0; i < reports.size(); ++i) o += (i ? ",\n" : "") + reports[i].json();
  return o + "\n]}\n";
}

bool reports_passed(const std::string& json, std::string* why) {
  auto say = [why](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  try {
    // JSON is YAML's flow style: yaml-cpp reads it.
    const YAML::Node doc = YAML::Load(json);
    if (!doc["reports"] || !doc["reports"].IsSequence() || doc["reports"].size() == 0)
      return say("no calibration report");
    for (const auto& r : doc["reports"]) {
      if (!r["passed"] || !r["passed"].as<bool>()) {
        std::string w = "the " + r["solver"].as<std::string>("?") + " solve of " +
                        r["subject"].as<std::string>("?") + " failed";
        if (r["failures"] && r["failures"].size() > 0)
          w += ": " + r["failures"][0].as<std::string>();
        return say(w);
      }
    }
    return true;
  } catch (const YAML::Exception& e) {
    return say(std::string("the calibration report cannot be read: ") + e.what());
  }
}

}  // namespace rangex
