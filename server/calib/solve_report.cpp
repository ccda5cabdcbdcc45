#include "calib/solve_report.h"

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

}  // namespace rangex
