// The control plane's records: /api/calibrations (versions and who uploaded and activated
// what when), /api/audit (the audit log, newest last).
#include <httplib.h>

#include "core/error.h"
#include "service/http_json.h"
#include "service/http_params.h"
#include "service/http_server.h"

namespace rangex {

using json = nlohmann::json;

void HttpServer::record_routes(httplib::Server& s) {
  s.Get("/api/calibrations", [this](const httplib::Request& req, httplib::Response& res) {
    const int lane = int(int_param(req.params, "lane", -1, -1, 1 << 20));
    json versions = json::array();
    for (const StoredCalibration& c : store_.calibrations(lane))
      versions.push_back({{"lane", c.lane},
                          {"id", c.id},
                          {"uploaded_ns", c.uploaded_ns},
                          {"active", c.active},
                          {"has_report", !c.report.empty()}});
    json events = json::array();
    for (const AuditEntry& e : store_.audit_entries(100000))
      if (e.what.rfind("calibration.", 0) == 0) events.push_back(audit_json(e));
    send_json(res, {{"versions", versions}, {"events", events}});
  });
  s.Get("/api/audit", [this](const httplib::Request& req, httplib::Response& res) {
    const int limit = int(int_param(req.params, "limit", 200, 1, 100000));
    json out = json::array();
    for (const AuditEntry& e : store_.audit_entries(limit)) out.push_back(audit_json(e));
    send_json(res, out);
  });
}

}  // namespace rangex
