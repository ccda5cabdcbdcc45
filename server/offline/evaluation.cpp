#include "offline/evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "pipeline/truth_heights.h"

namespace rangex {

ErrorAccumulator::ErrorAccumulator(double resolution, double max_abs)
    : res_(resolution), hist_(size_t(max_abs / resolution) + 2, 0) {}

void ErrorAccumulator::add(double e) {
  ++count_;
  sum_ += e;
  sum_abs_ += std::abs(e);
  hist_[std::min(hist_.size() - 1, size_t(std::abs(e) / res_))]++;
}

void ErrorAccumulator::merge(const ErrorAccumulator& o) {
  count_ += o.count_;
  sum_ += o.sum_;
  sum_abs_ += o.sum_abs_;
  for (size_t i = 0; i < hist_.size() && i < o.hist_.size(); ++i) hist_[i] += o.hist_[i];
}

ErrorStats ErrorAccumulator::stats() const {
  ErrorStats s;
  s.count = count_;
  if (!count_) return s;
  s.bias = sum_ / double(count_);
  s.mean_abs = sum_abs_ / double(count_);
  const size_t want = size_t(std::ceil(0.99 * double(count_)));
  size_t seen = 0;
  for (size_t i = 0; i < hist_.size(); ++i) {
    seen += hist_[i];
    if (seen >= want) {
      s.p99_abs = (double(i) + 1) * res_;  // upper edge of the bin: never optimistic
      break;
    }
  }
  return s;
}

LaneEvaluation evaluate_lane(const RecordingReader& rec, const LaneConfig& lc,
                             const std::vector<float> stripe_rows[2],
                             const std::vector<float>& thickness) {
  const RecordingInfo& info = rec.info();
  const int lane = lc.id;
  if (!info.has_truth) fail("recording ", rec.dir(), " has no truth/ to evaluate against");
  LaneEvaluation ev;
  ev.lane = lane;
  for (int c = 0; c < 2; ++c) {
    const auto truth = rec.truth_f32(lane, "stripe_cam" + std::to_string(c) + ".f32", info.width);
    if (truth.size() != stripe_rows[c].size())
      fail("lane ", lane, " camera ", c, ": ", stripe_rows[c].size(), " measured columns for ",
           truth.size(), " truth columns");
    std::vector<float> tz;
    std::vector<uint8_t> tv;
    TruthHeights(lc, c).heights(truth, info.width, tz, tv);
    ErrorAccumulator err, err_fillet;
    size_t with = 0, found = 0, without = 0, false_pos = 0;
    for (size_t i = 0; i < truth.size(); ++i) {
      const bool t = std::isfinite(truth[i]), m = std::isfinite(stripe_rows[c][i]);
      if (t) {
        ++with;
        if (m) {
          ++found;
          const double e = double(stripe_rows[c][i]) - truth[i];
          err.add(e);
          if (tz[i] > kFilletColumnMinMm) err_fillet.add(e);
        }
      } else {
        ++without;
        false_pos += m;
      }
    }
    ev.stripe[c] = err.stats();
    ev.stripe_fillet[c] = err_fillet.stats();
    ev.stripe_detected[c] = with ? double(found) / double(with) : 0;
    ev.stripe_false[c] = without ? double(false_pos) / double(without) : 0;
  }
  const auto truth_t = rec.truth_f32(lane, "thickness.f32", info.xray_pixels);
  if (truth_t.size() != thickness.size())
    fail("lane ", lane, ": ", thickness.size(), " thickness pixels for ", truth_t.size(),
         " truth pixels");
  ErrorAccumulator err;
  size_t fillet = 0;
  for (size_t i = 0; i < truth_t.size(); ++i) {
    if (!(truth_t[i] >= kFilletPixelMinMm)) continue;
    ++fillet;
    if (std::isfinite(thickness[i])) err.add(double(thickness[i]) - truth_t[i]);
  }
  ev.thickness = err.stats();
  ev.fillet_coverage = fillet ? double(ev.thickness.count) / double(fillet) : 0;
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
    os << ", ";
    stats_json(os, "stripe_px_fillet_cam0", e.stripe_fillet[0]);
    os << ", ";
    stats_json(os, "stripe_px_fillet_cam1", e.stripe_fillet[1]);
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
  char buf[320];
  os << "lane  stripe error px, fillet columns (all columns)          thickness error mm, fillet "
        "pixels\n";
  os << "      cam0 mean|e|  p99            cam1 mean|e|  p99            mean|e|   p99     bias  "
        "coverage\n";
  for (const LaneEvaluation& e : evs) {
    std::snprintf(buf, sizeof buf,
                  "%-5d %5.3f (%5.3f) %5.3f (%5.3f)  %5.3f (%5.3f) %5.3f (%5.3f)  %7.3f %7.3f "
                  "%7.3f  %6.2f%%\n",
                  e.lane, e.stripe_fillet[0].mean_abs, e.stripe[0].mean_abs,
                  e.stripe_fillet[0].p99_abs, e.stripe[0].p99_abs, e.stripe_fillet[1].mean_abs,
                  e.stripe[1].mean_abs, e.stripe_fillet[1].p99_abs, e.stripe[1].p99_abs,
                  e.thickness.mean_abs, e.thickness.p99_abs, e.thickness.bias,
                  100 * e.fillet_coverage);
    os << buf;
  }
  char tail[160];
  std::string found;
  for (const LaneEvaluation& e : evs) {
    std::snprintf(tail, sizeof tail, "%slane %d %.2f%%/%.2f%%", found.empty() ? "" : ", ", e.lane,
                  100 * e.stripe_detected[0], 100 * e.stripe_detected[1]);
    found += tail;
  }
  os << "stripe columns found (cam0/cam1): " << found << "\n";
  return os.str();
}

}  // namespace rangex
