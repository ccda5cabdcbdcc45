#include "offline/csv_points.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace rangex {

namespace {
std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) out.push_back(trim(cell));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}
}  // namespace

CsvColumns read_two_column_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) fail(path, ": cannot open");
  CsvColumns c;
  std::string line;
  size_t lineno = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++lineno;
    if (trim(line).empty()) continue;
    const auto cells = split(line);
    if (cells.size() != 2) fail(path, ":", lineno, ": expected 2 columns, found ", cells.size());
    if (!header) {
      c.x_name = cells[0];
      c.y_name = cells[1];
      header = true;
      continue;
    }
    double v[2];
    for (int k = 0; k < 2; ++k) {
      size_t used = 0;
      try {
        v[k] = std::stod(cells[k], &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != cells[k].size() || !std::isfinite(v[k]))
        fail(path, ":", lineno, ": column ", k + 1, " ('", k ? c.y_name : c.x_name,
             "') is not a finite number: '", cells[k], "'");
    }
    c.x.push_back(v[0]);
    c.y.push_back(v[1]);
  }
  if (!header) fail(path, ": empty file (expected a header such as 'T,lnI')");
  if (c.x.empty()) fail(path, ": no data rows after the header");
  return c;
}

}  // namespace rangex
