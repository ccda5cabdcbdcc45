#include "evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/error.h"

namespace rangex {

ErrorStats error_stats(std::vector<double> e) {
  ErrorStats s;
  s.count = e.size();
  if (e.empty()) return s;
  double sum = 0, sum_abs = 0;
  for (double& v : e) {
    sum += v;
    sum_abs += std::abs(v);
    v = std::abs(v);
  }
  s.bias = sum / double(e.size());
  s.mean_abs = sum_abs / double(e.size());
  const size_t k = std::min(e.size() - 1, size_t(std::ceil(0.99 * double(e.size()))) - 1);
  std::nth_element(e.begin(), e.begin() + long(k), e.end());
  s.p99_abs = e[k];
  return s;
}

LaneEvaluation evaluate_lane(const RecordingReader& rec, int lane,
                             const std::vector<float> stripe_rows[2],
                             const std::vector<float>& thickness) {
  const RecordingInfo& info = rec.info();
  if (!info.has_truth) fail("recording ", rec.dir(), " has no truth/ to evaluate against");
  LaneEvaluation ev;
  ev.lane = lane;
  for (int c = 0; c < 2; ++c) {
    const auto truth = rec.truth_f32(lane, "stripe_cam" + std::to_string(c) + ".f32", info.width);
    if (truth.size() != stripe_rows[c].size())
      fail("lane ", lane, " camera ", c, ": ", stripe_rows[c].size(), " measured columns for ",
           truth.size(), " truth columns");
    std::vector<double> err;
    size_t with = 0, found = 0, without = 0, false_pos = 0;
    for (size_t i = 0; i < truth.size(); ++i) {
      const bool t = std::isfinite(truth[i]), m = std::isfinite(stripe_rows[c][i]);
      if (t) {
        ++with;
        if (m) {
          ++found;
          err.push_back(double(stripe_rows[c][i]) - truth[i]);
        }
      } else {
        ++without;
        false_pos += m;
      }
    }
    ev.stripe[c] = error_stats(std::move(err));
    ev.stripe_detected[c] = with ? double(found) / double(with) : 0;
    ev.stripe_false[c] = without ? double(false_pos) / double(without) : 0;
  }
  const auto truth_t = rec.truth_f32(lane, "thickness.f32", info.xray_pixels);
  if (truth_t.size() != thickness.size())
    fail("lane ", lane, ": ", thickness.size(), " thickness pixels for ", truth_t.size(), " truth pixels");
  std::vector<double> err;
  size_t fillet = 0;
  for (size_t i = 0; i < truth_t.size(); ++i) {
    if (!(truth_t[i] >= kFilletPixelMinMm)) continue;
    ++fillet;
    if (std::isfinite(thickness[i])) err.push_back(double(thickness[i]) - truth_t[i]);
  }
  ev.fillet_coverage = fillet ? double(err.size()) / double(fillet) : 0;
  ev.thickness = error_stats(std::move(err));
  return ev;
}

namespace {
void stats_json(std::ostringstream& os, const char* name, const ErrorStats& s) {
  os << "\"" << name << "\": {\"count\": " << s.count << ", \"mean_abs\": " << s.mean_abs
     << ", \"p99_abs\": " << s.p99_abs << ", \"bias\": " << s.bias << "}";
}
}  // namespace

std::string evaluations_json(const std::vector<LaneEvaluation>& evs) {
  std::ostringstream os;
  os.precision(6);
  os << "{\"lanes\": [";
  for (size_t i = 0; i < evs.size(); ++i) {
    const LaneEvaluation& e = evs[i];
    os << (i ? ", " : "") << "{\"lane\": " << e.lane << ", ";
    stats_json(os, "stripe_px_cam0", e.stripe[0]);
    os << ", ";
    stats_json(os, "stripe_px_cam1", e.stripe[1]);
    os << ", \"stripe_detected\": [" << e.stripe_detected[0] << ", " << e.stripe_detected[1]
       << "], \"stripe_false\": [" << e.stripe_false[0] << ", " << e.stripe_false[1] << "], ";
    stats_json(os, "thickness_mm", e.thickness);
    os << ", \"fillet_coverage\": " << e.fillet_coverage << "}";
  }
  os << "]}";
  return os.str();
}

std::string evaluations_table(const std::vector<LaneEvaluation>& evs) {
  std::ostringstream os;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%-5s %-24s %-24s %-26s %s\n", "lane", "stripe cam0 px",
                "stripe cam1 px", "thickness mm (fillet px)", "coverage");
  os << buf;
  std::snprintf(buf, sizeof buf, "%-5s %-24s %-24s %-26s\n", "", "mean|err|  p99  found",
                "mean|err|  p99  found", "mean|err|  p99    bias");
  os << buf;
  for (const LaneEvaluation& e : evs) {
    std::snprintf(buf, sizeof buf,
                  "%-5d %7.3f %7.3f %6.1f%%   %7.3f %7.3f %6.1f%%   %7.3f %7.3f %7.3f   %6.2f%%\n",
                  e.lane, e.stripe[0].mean_abs, e.stripe[0].p99_abs, 100 * e.stripe_detected[0],
                  e.stripe[1].mean_abs, e.stripe[1].p99_abs, 100 * e.stripe_detected[1],
                  e.thickness.mean_abs, e.thickness.p99_abs, e.thickness.bias,
                  100 * e.fillet_coverage);
    os << buf;
  }
  return os.str();
}

}  // namespace rangex
