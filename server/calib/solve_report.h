// What every calibration solver reports (issue: residuals in pixels and mm, the standard
// deviation of every parameter, warnings), in one shape that is written as JSON beside
// the calibration YAML and stored with the calibration version.
#pragma once
#include <string>
#include <utility>
#include <vector>

namespace rangex {

struct Estimate {
  std::string name;
  double value = 0;
  double stddev = 0;  // 1 sigma from the fit's covariance; 0 when held fixed
  std::string unit;
};

struct SolveReport {
  std::string solver;   // camera, staircase, xray, registration, blur, scatter
  std::string subject;  // e.g. "lane 0 cam1"
  bool passed = true;   // every acceptance check of the solver held
  std::vector<Estimate> parameters;
  std::vector<std::pair<std::string, double>> figures;  // residual RMS/worst, coverage ...
  std::vector<std::string> warnings;
  std::vector<std::string> failures;  // why passed is false
  std::string json() const;
};

// Reports of several solvers as one JSON document {"reports": [...]} (read back by
// core/calibration_report.h when a set is activated).
std::string reports_json(const std::vector<SolveReport>& reports);

}  // namespace rangex
