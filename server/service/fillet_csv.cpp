#include "service/fillet_csv.h"

#include <httplib.h>

#include <cstdio>
#include <ctime>

#include "core/log.h"

namespace rangex {

namespace {
// RFC 4180: a field with a comma, quote or line break is quoted, quotes doubled.
std::string field(const std::string& v) {
  if (v.find_first_of(",\"\r\n") == std::string::npos) return v;
  std::string out = "\"";
  for (char c : v) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string utc(int64_t ns) {
  const std::time_t t = std::time_t(ns / 1'000'000'000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[80];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                int(ns / 1'000'000 % 1000));
  return buf;
}
}  // namespace

std::string fillet_csv_header() {
  return "uid,lane,lane_fillet,first_encoder,rows,decision,reason,decided_ns,decided_utc,"
         "calibration,beta0,beta1,beta2,resid_mean_dn,resid_std_dn,bones,air_pockets,"
         "fragments\r\n";
}

std::string fillet_csv_row(const StoredFillet& f) {
  int bones = 0, air = 0;
  std::string frags;  // kind x_mm y_mm area_mm2 peak_z meat_mm; ...
  for (const StoredFragment& g : f.fragments) {
    (g.kind == "bone" ? bones : air) += 1;
    if (!frags.empty()) frags += "; ";
    frags += g.kind + " " + num(g.x_mm) + " " + num(g.y_mm) + " " + num(g.area_mm2) + " " +
             num(g.peak_z) + " " + num(g.meat_mm);
  }
  std::string row;
  for (const std::string& v :
       {std::to_string(f.uid), std::to_string(f.lane), std::to_string(f.lane_fillet),
        std::to_string(f.first_encoder), std::to_string(f.rows), f.decision, f.reason,
        std::to_string(f.decided_ns), utc(f.decided_ns), f.calibration_id, num(f.beta0),
        num(f.beta1), num(f.beta2), num(f.resid_mean_dn), num(f.resid_std_dn),
        std::to_string(bones), std::to_string(air), frags}) {
    if (!row.empty()) row += ',';
    row += field(v);
  }
  return row + "\r\n";
}

void send_csv_pages(httplib::Response& res, const std::string& filename, std::string header,
                    std::function<bool(std::string&)> next_page,
                    const std::atomic<bool>& stopping) {
  res.set_header("Content-Disposition", "attachment; filename=\"" + filename + "\"");
  res.set_chunked_content_provider(
      "text/csv", [header = std::move(header), next_page = std::move(next_page), &stopping,
                   filename, first = true](size_t, httplib::DataSink& sink) mutable {
        std::string out = first ? std::move(header) : std::string();
        first = false;
        bool more = false;
        try {
          if (stopping) return false;
          more = next_page(out);
        } catch (const std::exception& e) {
          log::warn("csv_export_failed", "{}: a page failed, the download ends incomplete: {}",
                    filename, e.what());
          return false;
        }
        if (!sink.write(out.data(), out.size())) return false;
        if (!more) sink.done();
        return true;
      });
}

}  // namespace rangex
