// The plant as a whole: /api/info, /api/lanes, /api/statistics, /api/history, /metrics.
#include <httplib.h>

#include "core/error.h"
#include "service/http_json.h"
#include "service/http_params.h"
#include "service/http_server.h"
#include "service/metrics_text.h"
#include "service/pb_convert.h"

namespace rangex {

using json = nlohmann::json;

namespace {
// One line for the dashboard's header: where the records go and how far behind.
json forwarding_text(const std::optional<ForwarderStatus>& f) {
  if (!f) return nullptr;
  std::string t = "PostgreSQL " + f->state;
  if (f->lag_records > 0)
    t += ": " + std::to_string(f->lag_records) + " records (" +
         std::to_string(int64_t(f->lag_seconds)) + " s) waiting";
  return {{"text", t}, {"ok", f->connected}, {"error", f->last_error}};
}
}  // namespace

void HttpServer::plant_routes(httplib::Server& s) {
  s.Get("/api/info", [this](const httplib::Request&, httplib::Response& res) {
    const BackendInfo b = engine_.backend();
    send_json(res, {{"version", opt_.version},
                    {"plant", engine_.plant().name},
                    {"lanes", engine_.plant().lanes.size()},
                    {"backend", b.name},
                    {"device", b.device},
                    {"backend_note", engine_.backend_note()},
                    {"forwarding", forwarding_text(engine_.forwarding())},
                    {"now_ns", now_ns()}});
  });
  s.Get("/api/lanes", [this](const httplib::Request&, httplib::Response& res) {
    const std::string backend = engine_.backend().name;
    json out = json::array();
    for (const LaneState& l : engine_.lanes()) out.push_back(lane_json(l, history_, backend));
    send_json(res, out);
  });
  s.Get("/api/statistics", [this](const httplib::Request&, httplib::Response& res) {
    // GetStatistics itself, in protobuf's JSON mapping: the same fields, the same figures.
    v1::GetStatisticsResponse st;
    fill(&st, engine_.stats());
    st.set_subscribers(hub_.subscribers());
    st.set_subscribers_dropped(hub_.dropped());
    st.set_ingest_streams(opt_.ingest_streams ? opt_.ingest_streams() : 0);
    res.set_content(to_json(st), "application/json");
  });
  s.Get("/api/history", [this](const httplib::Request& req, httplib::Response& res) {
    const int64_t minutes = int_param(req.params, "minutes", 60, 1, 60);
    const std::vector<HistorySample> h = history_.since(now_ns() - minutes * 60'000'000'000);
    json out = json::array();
    for (size_t k = 1; k < h.size(); ++k) {
      const double dt = double(h[k].t_ns - h[k - 1].t_ns) / 1e9;
      if (dt <= 0) continue;
      out.push_back(
          {{"t_ns", h[k].t_ns},
           {"lines_per_s", double(h[k].processed - h[k - 1].processed) / dt},
           {"fillets_per_min", 60 * double(h[k].fillets - h[k - 1].fillets) / dt},
           {"rejects_per_min", 60 * double(h[k].rejects - h[k - 1].rejects) / dt},
           {"not_inspected_per_min", 60 * double(h[k].not_inspected - h[k - 1].not_inspected) / dt},
           {"decision_p50_ms", h[k].decision_p50_ms},
           {"decision_p99_ms", h[k].decision_p99_ms},
           {"inspection_p50_ms", h[k].inspection_p50_ms}});
    }
    send_json(res, {{"period_s", opt_.history_period_s}, {"samples", out}});
  });
  s.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
    MetricsInput m;
    m.stats = engine_.stats();
    m.lanes = engine_.lanes();
    m.subscribers = hub_.subscribers();
    m.subscribers_dropped = hub_.dropped();
    m.ingest_streams = opt_.ingest_streams ? opt_.ingest_streams() : 0;
    m.http_clients = event_streams_;
    res.set_content(prometheus_text(m), "text/plain; version=0.0.4; charset=utf-8");
  });
}

}  // namespace rangex
