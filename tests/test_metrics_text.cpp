// /metrics as a Prometheus scraper reads it: every sample after its family's HELP and TYPE,
// each family once, no sample twice, histograms cumulative up to +Inf = _count, label values
// escaped; and the figures it derives (lines of no lane, refusals of no lane, passed fillets)
// from the statistics it is given.
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "service/metrics_text.h"

namespace rangex {
namespace {

struct Sample {
  std::string name;
  std::map<std::string, std::string> labels;  // unescaped values
  std::string value;
};

struct Exposition {
  std::vector<std::string> families;         // in the order declared
  std::map<std::string, std::string> types;  // family -> counter | gauge | histogram
  std::vector<Sample> samples;
};

// Reads label pairs k="v",... from `s`; the value's escapes (\\, \", \n) undone.
std::map<std::string, std::string> parse_labels(const std::string& s) {
  std::map<std::string, std::string> out;
  size_t i = 0;
  while (i < s.size()) {
    const size_t eq = s.find('=', i);
    EXPECT_NE(eq, std::string::npos) << s;
    if (eq == std::string::npos) break;
    const std::string key = s.substr(i, eq - i);
    EXPECT_EQ(s[eq + 1], '"') << s;
    std::string v;
    size_t k = eq + 2;
    for (; k < s.size() && s[k] != '"'; ++k) {
      if (s[k] == '\\') {
        ++k;
        EXPECT_TRUE(s[k] == '\\' || s[k] == '"' || s[k] == 'n') << "bad escape in " << s;
        v += s[k] == 'n' ? '\n' : s[k];
      } else {
        EXPECT_NE(s[k], '\n') << "a raw newline in " << s;
        v += s[k];
      }
    }
    EXPECT_LT(k, s.size()) << "unterminated value in " << s;
    EXPECT_TRUE(out.emplace(key, v).second) << "label " << key << " twice in " << s;
    i = k + 1;
    if (i < s.size()) {
      EXPECT_EQ(s[i], ',') << s;
      ++i;
    }
  }
  return out;
}

// The family a sample belongs to: a histogram's _bucket, _sum and _count are its own.
std::string family_of(const std::string& name, const std::map<std::string, std::string>& types) {
  for (const char* suffix : {"_bucket", "_sum", "_count"}) {
    const std::string sfx = suffix;
    if (name.size() > sfx.size() && name.compare(name.size() - sfx.size(), sfx.size(), sfx) == 0) {
      const std::string base = name.substr(0, name.size() - sfx.size());
      if (auto it = types.find(base); it != types.end() && it->second == "histogram") return base;
    }
  }
  return name;
}

Exposition parse(const std::string& text) {
  Exposition e;
  EXPECT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n');
  std::istringstream in(text);
  std::string line, helped;
  std::set<std::pair<std::string, std::map<std::string, std::string>>> seen;
  while (std::getline(in, line)) {
    if (line.rfind("# HELP ", 0) == 0) {
      helped = line.substr(7, line.find(' ', 7) - 7);
      continue;
    }
    if (line.rfind("# TYPE ", 0) == 0) {
      std::istringstream t(line.substr(7));
      std::string name, type;
      t >> name >> type;
      EXPECT_EQ(name, helped) << "TYPE without its HELP just before: " << line;
      EXPECT_TRUE(type == "counter" || type == "gauge" || type == "histogram") << line;
      EXPECT_TRUE(e.types.emplace(name, type).second) << "family declared twice: " << name;
      e.families.push_back(name);
      continue;
    }
    Sample s;
    const size_t brace = line.find('{'), space = line.rfind(' '), close = line.rfind('}');
    if (space == std::string::npos || (brace != std::string::npos && close == std::string::npos)) {
      ADD_FAILURE() << "not a sample: " << line;
      continue;
    }
    if (brace != std::string::npos && brace < space) {
      s.name = line.substr(0, brace);
      s.labels = parse_labels(line.substr(brace + 1, close - brace - 1));
    } else {
      s.name = line.substr(0, space);
    }
    s.value = line.substr(space + 1);
    size_t used = 0;
    std::stod(s.value, &used);
    EXPECT_EQ(used, s.value.size()) << "not a number: " << line;
    const std::string fam = family_of(s.name, e.types);
    EXPECT_FALSE(e.families.empty()) << line;
    if (!e.families.empty())
      EXPECT_EQ(fam, e.families.back()) << "a sample outside its family's block: " << line;
    EXPECT_TRUE(seen.emplace(s.name, s.labels).second) << "sample twice: " << line;
    e.samples.push_back(s);
  }
  return e;
}

// The value of the one sample of `name` whose labels include `labels`.
double value(const Exposition& e, const std::string& name,
             const std::map<std::string, std::string>& labels = {}) {
  const Sample* found = nullptr;
  for (const Sample& s : e.samples) {
    if (s.name != name) continue;
    bool all = true;
    for (const auto& [k, v] : labels) {
      const auto it = s.labels.find(k);
      all = all && it != s.labels.end() && it->second == v;
    }
    if (!all) continue;
    EXPECT_EQ(found, nullptr) << "more than one " << name;
    found = &s;
  }
  EXPECT_NE(found, nullptr) << "no " << name;
  return found ? std::stod(found->value) : -12345;
}

size_t count(const Exposition& e, const std::string& name) {
  size_t n = 0;
  for (const Sample& s : e.samples) n += s.name == name;
  return n;
}

LatencyStats::Summary latencies(std::initializer_list<double> ms) {
  LatencyStats l;
  for (double v : ms) l.add(v);
  return l.summary();
}

// A plant as a scrape sees it mid-shift: two lanes, refusals of a lane and of none, a PLC,
// forwarding, one lane fed by its own sensors, one with learned thresholds.
MetricsInput busy_plant() {
  MetricsInput m;
  EngineStats& s = m.stats;
  s.received = 1000;
  s.refused = {{"BAD_SIZE", 7}, {"UNKNOWN_LANE", 3}};
  s.queue_wait = latencies({0.2, 3, 3, 45, 7000, 20000});
  s.pipeline = latencies({12, 14});
  s.inspection = latencies({80, 95, 110});
  s.inspection_stages = {{"match kernels", latencies({20})}, {"segment", latencies({5, 6})}};
  s.decision = latencies({150});
  s.queue_depth = 17;
  s.queue_capacity = 2048;
  s.lines_per_second = 2412.5;
  s.health.serving = true;
  s.backend = {};
  s.backend.name = "vulkan";
  s.backend.device = "llvmpipe (LLVM 15.0.6, 256 bits)";
  s.batches.batches = 40;
  s.batches.verified = 2;
  s.store_errors = 1;
  PlcStatus p;
  p.enabled = p.connected = true;
  p.address = "10.0.0.7:502";
  p.released = 30;
  p.diverted = 4;
  s.plc = p;
  ForwarderStatus f;
  f.server_id = "srv-a";
  f.lag_records = -3;  // a head behind the forwarded count reads as no lag, not as a wrap
  f.links = 12;
  s.forwarding = f;
  for (int id : {0, 1}) {
    LaneState l;
    l.config.id = id;
    l.received = id == 0 ? 600 : 380;
    l.processed = l.received - 2;
    l.fillets = 10;
    l.rejects = 2;
    l.not_inspected = 1;
    l.restarts = id;
    l.idle_ms = id == 0 ? 1500 : -1;
    l.calibration_id = id == 0 ? "cal \"7\" \\ night\nshift" : "shipped";
    if (id == 0) {
      l.refused = {{"BAD_SIZE", 5}};
      l.dropped = {{"processing error", 2}};
      l.config.inspection.learned.band_edges_mm = {0, 12, 40};
      l.config.inspection.learned.version = "learn-3";
      l.implied_frr = 0.004;
    } else {
      LaneSensors ls;
      ls.lane = 1;
      SensorState cam, xray;
      cam.role = "cam0";
      cam.device = "Basler-1";
      cam.state = "streaming";
      cam.frames = 90;
      xray.role = "xray";
      xray.device = "10.0.1.9";
      xray.state = "lost";
      xray.reconnects = 2;
      ls.devices = {cam, xray};
      l.sensors = ls;
    }
    m.lanes.push_back(l);
  }
  m.subscribers = 3;
  m.subscribers_dropped = 4;
  m.http_clients = 1;
  m.ingest_streams = 2;
  m.stats.open_files = 17;
  m.stats.open_files_limit = 20000;
  return m;
}

TEST(MetricsText, AScraperReadsEveryFamilyOnceAndEverySampleInItsFamily) {
  const Exposition e = parse(prometheus_text(busy_plant()));
  EXPECT_EQ(e.types.at("rangex_lines_received_total"), "counter");
  EXPECT_EQ(e.types.at("rangex_stage_latency_seconds"), "histogram");
  EXPECT_EQ(e.types.at("rangex_queue_depth_lines"), "gauge");
  EXPECT_EQ(e.types.at("rangex_subscribers_dropped_total"), "counter");
  EXPECT_EQ(value(e, "rangex_subscribers_dropped_total", {}), 4);
  EXPECT_EQ(e.types.at("rangex_open_files"), "gauge");
  EXPECT_EQ(value(e, "rangex_open_files", {}), 17);
  EXPECT_EQ(value(e, "rangex_open_files_limit", {}), 20000);
  EXPECT_GE(e.families.size(), 40u);
}

TEST(MetricsText, DerivesLanelessLinesRefusalsAndPassedFillets) {
  const Exposition e = parse(prometheus_text(busy_plant()));
  EXPECT_EQ(value(e, "rangex_lines_received_total", {{"lane", "0"}}), 600);
  EXPECT_EQ(value(e, "rangex_lines_received_total", {{"lane", "none"}}), 20);
  EXPECT_EQ(value(e, "rangex_lines_refused_total", {{"lane", "0"}, {"code", "BAD_SIZE"}}), 5);
  EXPECT_EQ(value(e, "rangex_lines_refused_total", {{"lane", "none"}, {"code", "BAD_SIZE"}}), 2);
  EXPECT_EQ(value(e, "rangex_lines_refused_total", {{"lane", "none"}, {"code", "UNKNOWN_LANE"}}),
            3);
  EXPECT_EQ(value(e, "rangex_fillets_total", {{"lane", "1"}, {"decision", "pass"}}), 7);
  EXPECT_EQ(value(e, "rangex_lines_dropped_total", {{"reason", "processing error"}}), 2);
  EXPECT_EQ(value(e, "rangex_forward_lag_records"), 0);
  EXPECT_EQ(value(e, "rangex_plc_least_spare_seconds"), -1);
  EXPECT_EQ(value(e, "rangex_lane_idle_seconds", {{"lane", "0"}}), 1.5);
  EXPECT_EQ(count(e, "rangex_lane_idle_seconds"), 1u);  // lane 1 was never fed
}

TEST(MetricsText, SensorsAndLearnedThresholdsOnlyWhereALaneHasThem) {
  const Exposition e = parse(prometheus_text(busy_plant()));
  EXPECT_EQ(value(e, "rangex_sensor_up", {{"role", "cam0"}}), 1);
  EXPECT_EQ(value(e, "rangex_sensor_up", {{"role", "xray"}}), 0);
  EXPECT_EQ(value(e, "rangex_sensor_reconnects_total", {{"device", "10.0.1.9"}}), 2);
  EXPECT_EQ(count(e, "rangex_sensor_frames_total"), 2u);
  EXPECT_EQ(value(e, "rangex_lane_implied_false_reject_rate", {{"version", "learn-3"}}), 0.004);
  EXPECT_EQ(count(e, "rangex_lane_product_drift"), 1u);
  // A plant without a PLC or a plant-wide database has no such families.
  MetricsInput bare = busy_plant();
  bare.stats.plc.reset();
  bare.stats.forwarding.reset();
  const Exposition b = parse(prometheus_text(bare));
  EXPECT_EQ(b.types.count("rangex_plc_up"), 0u);
  EXPECT_EQ(b.types.count("rangex_forward_up"), 0u);
}

TEST(MetricsText, HistogramsAreCumulativeUpToTheirCountInSeconds) {
  const Exposition e = parse(prometheus_text(busy_plant()));
  std::map<std::string, std::vector<std::pair<double, double>>> buckets;  // stage -> (le, n)
  for (const Sample& s : e.samples)
    if (s.name == "rangex_stage_latency_seconds_bucket") {
      const std::string le = s.labels.at("le");
      buckets[s.labels.at("stage")].push_back(
          {le == "+Inf" ? 1e300 : std::stod(le), std::stod(s.value)});
    }
  ASSERT_TRUE(buckets.count("inspection_match_kernels")) << "a stage's spaces become '_'";
  for (const auto& [stage, b] : buckets) {
    for (size_t k = 1; k < b.size(); ++k) {
      EXPECT_GT(b[k].first, b[k - 1].first) << stage;
      EXPECT_GE(b[k].second, b[k - 1].second) << stage;
    }
    EXPECT_EQ(b.back().first, 1e300) << stage << ": the last bucket is +Inf";
    EXPECT_EQ(b.back().second, value(e, "rangex_stage_latency_seconds_count", {{"stage", stage}}))
        << stage;
  }
  const auto& q = buckets.at("queue_wait");
  EXPECT_EQ(q.front(), (std::pair<double, double>{0.0005, 1}));  // 0.2 ms <= 0.5 ms
  EXPECT_EQ(q[q.size() - 2].second, 5);  // 20 s is above the last bound (10 s)
  EXPECT_DOUBLE_EQ(value(e, "rangex_stage_latency_seconds_sum", {{"stage", "queue_wait"}}),
                   (0.2 + 3 + 3 + 45 + 7000 + 20000) / 1e3);
  EXPECT_EQ(value(e, "rangex_decision_latency_seconds_count"), 1);
}

TEST(MetricsText, LabelValuesAreEscaped) {
  const std::string text = prometheus_text(busy_plant());
  EXPECT_NE(text.find(R"(calibration="cal \"7\" \\ night\nshift")"), std::string::npos);
  const Exposition e = parse(text);
  EXPECT_EQ(
      value(e, "rangex_lane_calibration_info", {{"calibration", "cal \"7\" \\ night\nshift"}}), 1);
  EXPECT_EQ(value(e, "rangex_backend_info", {{"device", "llvmpipe (LLVM 15.0.6, 256 bits)"}}), 1);
}

}  // namespace
}  // namespace rangex
