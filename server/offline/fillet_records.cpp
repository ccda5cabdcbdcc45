#include "offline/fillet_records.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/json_text.h"

namespace fs = std::filesystem;

namespace rangex {

void RecordSet::add(const FilletResult& r) {
  FilletRecord f;
  f.lane = r.lane;
  f.fillet = r.id;
  f.first_line = r.first_line;
  f.rows = r.rows;
  f.y0_mm = r.y0_mm;
  f.y1_mm = r.y0_mm + r.rows * r.step_mm;
  f.x0_mm = r.x0_mm;
  f.x1_mm = r.x0_mm + r.cols * r.pitch_mm;
  f.decision = std::string(decision_name(r.decision));
  f.beta0 = r.fit.beta0;
  f.beta1 = r.fit.beta1;
  f.scale = r.fit.scale;
  f.iterations = r.fit.iterations;
  f.converged = r.fit.converged;
  f.pixels = r.pixels;
  f.resid_mean_dn = r.resid_mean_dn;
  f.resid_std_dn = r.resid_std_dn;
  f.fragments = int(r.fragments.size());
  f.air_pockets = int(r.air_pockets.size());
  f.reason = r.reason;
  fillets.push_back(f);
  for (const auto* list : {&r.fragments, &r.air_pockets})
    for (const Blob& b : *list)
      fragments.push_back({r.lane, r.id, list == &r.fragments ? "bone" : "air", b.x_mm, b.y_mm,
                           b.area_mm2, b.peak_z, b.attenuation_mm2, b.meat_mm, b.bone_mg});
  for (const BandExtreme& e : r.extremes) extremes.push_back({r.lane, r.id, e});
}

void write_records(const std::string& dir, const std::string& prefix, const RecordSet& s) {
  fs::create_directories(dir);
  const fs::path fp = fs::path(dir) / (prefix + "fillets.csv");
  std::ofstream f(fp);
  f << "lane,fillet,first_line,rows,y0_mm,y1_mm,x0_mm,x1_mm,decision,beta0,beta1,scale,"
       "iterations,converged,pixels,resid_mean_dn,resid_std_dn,fragments,air_pockets,reason\n";
  char buf[512];
  for (const FilletRecord& r : s.fillets) {
    std::snprintf(buf, sizeof buf,
                  "%d,%lld,%lld,%d,%.3f,%.3f,%.3f,%.3f,%s,%.9g,%.9g,%.6g,%d,%d,%d,%.4f,%.4f,%d,%d,",
                  r.lane, (long long)r.fillet, (long long)r.first_line, r.rows, r.y0_mm, r.y1_mm,
                  r.x0_mm, r.x1_mm, r.decision.c_str(), r.beta0, r.beta1, r.scale, r.iterations,
                  int(r.converged), r.pixels, r.resid_mean_dn, r.resid_std_dn, r.fragments,
                  r.air_pockets);
    std::string reason = r.reason;
    for (char& c : reason)
      if (c == '\n') c = ' ';
    f << buf << reason << "\n";  // free text last: commas in it stay in the field
  }
  if (!f) fail(fp.string(), ": write failed");
  const fs::path gp = fs::path(dir) / (prefix + "fragments.csv");
  std::ofstream g(gp);
  g << "lane,fillet,kind,x_mm,y_mm,area_mm2,peak_z,attenuation_mm2,meat_mm,bone_mg\n";
  for (const FragmentRecord& b : s.fragments) {
    std::snprintf(buf, sizeof buf, "%d,%lld,%s,%.3f,%.3f,%.3f,%.3f,%.5f,%.3f,%.4f\n", b.lane,
                  (long long)b.fillet, b.kind.c_str(), b.x_mm, b.y_mm, b.area_mm2, b.peak_z,
                  b.attenuation_mm2, b.meat_mm, b.bone_mg);
    g << buf;
  }
  if (!g) fail(gp.string(), ": write failed");
  const fs::path ep = fs::path(dir) / (prefix + "extremes.csv");
  std::ofstream e(ep);
  e << "lane,fillet,statistic,band,extreme,pixels,thickness_mm\n";
  for (const ExtremeRecord& x : s.extremes) {
    std::snprintf(buf, sizeof buf, "%d,%lld,%s,%d,%.6g,%.0f,%.3f\n", x.lane, (long long)x.fillet,
                  statistic_name(x.extreme.stat), x.extreme.band, x.extreme.x, x.extreme.n,
                  x.extreme.t);
    e << buf;
  }
  if (!e) fail(ep.string(), ": write failed");
}

namespace {
std::vector<std::string> split(const std::string& line, size_t max_fields) {
  std::vector<std::string> out;
  size_t start = 0;
  while (out.size() + 1 < max_fields) {
    const size_t comma = line.find(',', start);
    if (comma == std::string::npos) break;
    out.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
  out.push_back(line.substr(start));
  return out;
}

// A table of `fields` columns, or of as many as its header names up to `max_fields` (a
// column added since: older files read as before).
template <typename F>
void read_table(const fs::path& p, size_t fields, F&& row, size_t max_fields = 0) {
  std::ifstream in(p);
  if (!in) fail(p.string(), " is missing (was it written by 'rangexctl process'?)");
  std::string line;
  std::getline(in, line);
  const size_t named = size_t(std::count(line.begin(), line.end(), ',')) + 1;
  if (max_fields > fields && named > fields && named <= max_fields) fields = named;
  size_t n = 1;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    const auto c = split(line, fields);
    if (c.size() != fields)
      fail(p.string(), ":", n, ": expected ", fields, " fields, found ", c.size());
    try {
      row(c);
    } catch (const std::exception& e) {
      fail(p.string(), ":", n, ": malformed (", e.what(), ")");
    }
  }
}
}  // namespace

RecordSet read_records(const std::string& dir, const std::string& prefix) {
  RecordSet s;
  read_table(fs::path(dir) / (prefix + "fillets.csv"), 20, [&](const std::vector<std::string>& c) {
    FilletRecord r;
    r.lane = std::stoi(c[0]);
    r.fillet = std::stoll(c[1]);
    r.first_line = std::stoll(c[2]);
    r.rows = std::stoi(c[3]);
    r.y0_mm = std::stod(c[4]);
    r.y1_mm = std::stod(c[5]);
    r.x0_mm = std::stod(c[6]);
    r.x1_mm = std::stod(c[7]);
    r.decision = c[8];
    r.beta0 = std::stod(c[9]);
    r.beta1 = std::stod(c[10]);
    r.scale = std::stod(c[11]);
    r.iterations = std::stoi(c[12]);
    r.converged = std::stoi(c[13]) != 0;
    r.pixels = std::stoi(c[14]);
    r.resid_mean_dn = std::stod(c[15]);
    r.resid_std_dn = std::stod(c[16]);
    r.fragments = std::stoi(c[17]);
    r.air_pockets = std::stoi(c[18]);
    r.reason = c[19];
    s.fillets.push_back(r);
  });
  read_table(
      fs::path(dir) / (prefix + "fragments.csv"), 9,
      [&](const std::vector<std::string>& c) {
        s.fragments.push_back({std::stoi(c[0]), std::stoll(c[1]), c[2], std::stod(c[3]),
                               std::stod(c[4]), std::stod(c[5]), std::stod(c[6]), std::stod(c[7]),
                               std::stod(c[8]), c.size() > 9 ? std::stod(c[9]) : 0.0});
      },
      10);
  if (const fs::path ep = fs::path(dir) / (prefix + "extremes.csv"); fs::exists(ep))
    read_table(ep, 7, [&](const std::vector<std::string>& c) {
      BandExtreme e;
      e.stat = parse_statistic(c[2]);
      e.band = std::stoi(c[3]);
      e.x = std::stod(c[4]);
      e.n = std::stod(c[5]);
      e.t = std::stod(c[6]);
      s.extremes.push_back({std::stoi(c[0]), std::stoll(c[1]), e});
    });
  return s;
}

std::string fillets_json(const RecordSet& s) {
  std::ostringstream os;
  os.precision(8);
  os << "[";
  for (size_t i = 0; i < s.fillets.size(); ++i) {
    const FilletRecord& r = s.fillets[i];
    os << (i ? ",\n " : "\n ") << "{\"lane\": " << r.lane << ", \"fillet\": " << r.fillet
       << ", \"first_line\": " << r.first_line << ", \"rows\": " << r.rows << ", \"belt_mm\": ["
       << r.y0_mm << ", " << r.y1_mm << "], \"decision\": \"" << r.decision
       << "\", \"reason\": " << json_text(r.reason) << ", \"beta0\": " << r.beta0
       << ", \"beta1\": " << r.beta1 << ", \"scale\": " << r.scale
       << ", \"iterations\": " << r.iterations
       << ", \"converged\": " << (r.converged ? "true" : "false") << ", \"pixels\": " << r.pixels
       << ", \"residual_mean_dn\": " << r.resid_mean_dn
       << ", \"residual_std_dn\": " << r.resid_std_dn << ", \"fragments\": [";
    bool first = true;
    for (const FragmentRecord& b : s.fragments) {
      if (b.lane != r.lane || b.fillet != r.fillet || b.kind != "bone") continue;
      os << (first ? "" : ", ") << "{\"x_mm\": " << b.x_mm << ", \"y_mm\": " << b.y_mm
         << ", \"area_mm2\": " << b.area_mm2 << ", \"peak_z\": " << b.peak_z
         << ", \"attenuation_mm2\": " << b.attenuation_mm2 << ", \"meat_mm\": " << b.meat_mm
         << ", \"bone_mg\": " << b.bone_mg << "}";
      first = false;
    }
    os << "], \"air_pockets\": " << r.air_pockets << "}";
  }
  os << "\n]\n";
  return os.str();
}

}  // namespace rangex
