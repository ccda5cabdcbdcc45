// The fleet's control-plane records: every server's calibration and learned-settings
// versions with who did what when, and the audit log across servers.
#include <httplib.h>

#include "fleet/fleet_records.h"
#include "fleet/fleet_server.h"
#include "plantdb/pg_pool.h"
#include "service/http_json.h"
#include "service/http_params.h"

namespace rangex {

using json = nlohmann::json;

namespace {
json fleet_audit_json(const FleetAudit& a) {
  json j = audit_json(a.e);
  j["server"] = a.server;
  return j;
}
}  // namespace

void FleetServer::record_routes(httplib::Server& s) {
  s.Get("/api/calibrations", [this](const httplib::Request& req, httplib::Response& res) {
    const int lane = int(int_param(req.params, "lane", -1, -1, 1 << 20));
    PgPool::Lease db = db_->take();
    json versions = json::array();
    for (const FleetSetting& v : fleet_settings(*db, lane))
      versions.push_back({{"server", v.server},
                          {"kind", v.kind},
                          {"lane", v.lane},
                          {"id", v.id},
                          {"uploaded_ns", v.uploaded_ns},
                          {"active", v.active},
                          {"has_report", v.has_report}});
    json events = json::array();
    for (const FleetAudit& a : fleet_audit(*db, 100000, {"calibration.", "learned."}))
      events.push_back(fleet_audit_json(a));
    send_json(res, {{"versions", versions}, {"events", events}});
  });
  s.Get("/api/audit", [this](const httplib::Request& req, httplib::Response& res) {
    const int limit = int(int_param(req.params, "limit", 200, 1, 100000));
    PgPool::Lease db = db_->take();
    json out = json::array();
    for (const FleetAudit& a : fleet_audit(*db, limit)) out.push_back(fleet_audit_json(a));
    send_json(res, out);
  });
}

}  // namespace rangex
