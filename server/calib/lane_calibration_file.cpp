#include "calib/lane_calibration_file.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/text_file.h"

namespace fs = std::filesystem;

namespace rangex {

LaneConfig load_lane_calibration(const PlantConfig& plant, int lane, const std::string& file) {
  const LaneConfig& base = plant.lane(lane);
  if (file.empty() || !fs::exists(file)) return base;
  return apply_lane_calibration(base, read_text_file(file), file);
}

void apply_calibration_option(PlantConfig& plant, const std::string& value) {
  std::stringstream list(value);
  std::string item;
  while (std::getline(list, item, ',')) {
    const size_t colon = item.find(':');
    const bool one =
        colon != std::string::npos && colon > 0 && item.find_first_not_of("0123456789") == colon;
    for (auto& l : plant.lanes)
      if (!one || l.id == std::stoi(item.substr(0, colon))) {
        const std::string file = one ? item.substr(colon + 1) : item;
        if (!std::filesystem::exists(file)) fail(file, ": no such calibration file");
        l = load_lane_calibration(plant, l.id, file);
      }
  }
}

void save_lane_calibration(const LaneConfig& lane, const std::string& file,
                           const SolveReport& report) {
  {
    std::ofstream out(file);
    out << "# rangex lane " << lane.id << " calibration, written by rangexctl calib "
        << report.solver << "\n"
        << lane_calibration_yaml(lane);
    if (!out) fail(file, ": write failed");
  }
  const fs::path dir = file + ".reports";
  fs::create_directories(dir);
  std::string name = report.solver + "-" + report.subject;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-') c = '_';
  std::ofstream out(dir / (name + ".json"));
  out << reports_json({report});
  if (!out) fail((dir / name).string(), ": write failed");
}

std::string lane_reports_json(const std::string& file) {
  const fs::path dir = file + ".reports";
  if (!fs::is_directory(dir)) return "";
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".json") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  std::string body;
  for (const auto& p : files) {
    // Each file is {"reports": [\n<one report>\n]}: take the report between the brackets.
    const std::string t = read_text_file(p.string());
    const size_t a = t.find('['), b = t.rfind(']');
    if (a == std::string::npos || b == std::string::npos || b <= a) continue;
    body += (body.empty() ? "" : ",\n") + t.substr(a + 1, b - a - 1);
  }
  return body.empty() ? "" : "{\"reports\": [" + body + "]}\n";
}

}  // namespace rangex
