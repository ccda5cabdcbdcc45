// rangexd's metrics in the Prometheus text exposition format (version 0.0.4): counters of
// lines and fillets by lane, latency histograms by stage, gauges of the queue, subscribers,
// the backend and each lane's active calibration. Built from the same engine statistics as
// GetStatistics, so the two always agree.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "service/engine.h"

namespace rangex {

struct MetricsInput {
  EngineStats stats;
  std::vector<LaneState> lanes;
  int subscribers = 0;               // results subscribers (gRPC streams and event streams)
  uint64_t subscribers_dropped = 0;  // of them, those that fell behind and gave way
  int ingest_streams = 0;            // open StreamLines calls
  int http_clients = 0;              // live event streams of the web dashboard
};

std::string prometheus_text(const MetricsInput& m);

}  // namespace rangex
