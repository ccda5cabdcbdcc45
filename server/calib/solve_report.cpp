#include "calib/solve_report.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/json_text.h"

namespace rangex {

namespace {

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

}  // namespace

std::string SolveReport::json() const {
  std::ostringstream o;
  o << "{\"solver\": " << json_text(solver) << ", \"subject\": " << json_text(subject)
    << ", \"passed\": " << (passed ? "true" : "false") << ",\n  \"parameters\": [";
  for (size_t i = 0; i < parameters.size(); ++i) {
    const Estimate& e = parameters[i];
    o << (i ? ",\n    " : "\n    ") << "{\"name\": " << json_text(e.name)
      << ", \"value\": " << number(e.value) << ", \"std\": " << number(e.stddev)
      << ", \"unit\": " << json_text(e.unit) << "}";
  }
  o << "],\n  \"figures\": {";
  for (size_t i = 0; i < figures.size(); ++i)
    o << (i ? ", " : "") << json_text(figures[i].first) << ": " << number(figures[i].second);
  o << "},\n  \"warnings\": [";
  for (size_t i = 0; i < warnings.size(); ++i) o << (i ? ", " : "") << json_text(warnings[i]);
  o << "],\n  \"failures\": [";
  for (size_t i = 0; i < failures.size(); ++i) o << (i ? ", " : "") << json_text(failures[i]);
  o << "]}";
  return o.str();
}

std::string reports_json(const std::vector<SolveReport>& reports) {
  std::string o = "{\"reports\": [\n";
  for (size_t i = 0; i < reports.size(); ++i) o += (i ? ",\n" : "") + reports[i].json();
  return o + "\n]}\n";
}

}  // namespace rangex
