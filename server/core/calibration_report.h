// Whether a calibration set's report (the solvers' JSON document, calib/solve_report.h)
// says the solve passed: activation refuses a set whose report is missing or failed
// unless forced.
#pragma once
#include <string>

namespace rangex {

struct ReportStatus {
  bool present = false;
  bool passed = false;
  std::string why;  // what is missing or failed; empty when passed
};

// Empty text: not present. Unreadable JSON, no reports, or any report with
// "passed": false: present but not passed, with the first failure in `why`.
ReportStatus check_calibration_report(const std::string& json);

}  // namespace rangex
