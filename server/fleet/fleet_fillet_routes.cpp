// The fleet's fillets: a page across servers, every match as CSV, one fillet, and its images
// fetched from the server that keeps them.
#include <httplib.h>

#include "core/error.h"
#include "fleet/fleet_records.h"
#include "fleet/fleet_server.h"
#include "fleet/image_relay.h"
#include "plantdb/pg_pool.h"
#include "service/fillet_csv.h"
#include "service/http_json.h"
#include "service/http_params.h"

namespace rangex {

using json = nlohmann::json;

namespace {
FleetQuery fleet_query(const httplib::Request& req) {
  // `after` is the fleet's own cursor (FleetCursor), not a uid: read apart.
  QueryParams p = req.params;
  p.erase("after");
  FleetQuery fq;
  fq.q = fillet_query(p);
  fq.server = req.get_param_value("server");
  fq.after = FleetCursor::parse(req.get_param_value("after"));
  return fq;
}

json fleet_fillet_json(const FleetFillet& f) {
  json j = fillet_json(f.f);
  j["server"] = f.server;
  j["images"] = f.images;
  return j;
}

// Server ids are letters, digits, '-', '_' and '.' (plant.server_id).
constexpr const char* kFillet = R"(/api/fillets/([A-Za-z0-9._-]+)/(\d+))";
}  // namespace

void FleetServer::fillet_routes(httplib::Server& s) {
  s.Get("/api/fillets", [this](const httplib::Request& req, httplib::Response& res) {
    const FleetQuery fq = fleet_query(req);
    PgPool::Lease db = db_->take();
    json list = json::array();
    FleetCursor last = fq.after;
    for (const FleetFillet& f : fleet_fillets(*db, fq)) {
      list.push_back(fleet_fillet_json(f));
      last = {f.f.decided_ns, f.server, f.f.uid};
    }
    // `next_after` continues the search where this page ended.
    send_json(res, {{"fillets", list},
                    {"next_after",
                     fq.q.newest_first || last.decided_ns < 0 ? fq.after.text() : last.text()}});
  });
  s.Get("/api/fillets.csv", [this](const httplib::Request& req, httplib::Response& res) {
    auto fq = std::make_shared<FleetQuery>(fleet_query(req));  // refused here: 400
    fq->q.limit = kCsvPage;
    fq->q.newest_first = false;
    { PgPool::Lease db = db_->take(); }  // a database that does not answer: 503, not a cut
    send_csv_pages(
        res, "rangex-fleet-fillets.csv", "server," + fillet_csv_header(),
        [this, fq](std::string& out) {
          PgPool::Lease db = db_->take();  // a page at a time: a slow reader holds none
          const std::vector<FleetFillet> page = fleet_fillets(*db, *fq);
          for (const FleetFillet& f : page) out += f.server + "," + fillet_csv_row(f.f);
          if (int(page.size()) < fq->q.limit) return false;
          fq->after = {page.back().f.decided_ns, page.back().server, page.back().f.uid};
          return true;
        },
        stopping_);
  });
  s.Get(kFillet, [this](const httplib::Request& req, httplib::Response& res) {
    const std::string server = req.matches[1];
    const int64_t uid = parse_uid(req.matches[2]);
    PgPool::Lease db = db_->take();
    const std::optional<FleetFillet> f = fleet_fillet(*db, server, uid);
    if (!f) throw NotFound("no fillet " + std::to_string(uid) + " of server " + server);
    json j = fleet_fillet_json(*f);
    if (const std::optional<FleetServerRow> r = fleet_server(*db, server))
      j["kept_by"] = {{"server", r->id}, {"http", r->http}, {"state", server_state(*r, now_ns())}};
    send_json(res, j);
  });
  s.Get(std::string(kFillet) + "/images/([a-z_]+)",
        [this](const httplib::Request& req, httplib::Response& res) {
          const std::string server = req.matches[1];
          const int64_t uid = parse_uid(req.matches[2]);
          const std::string kind = checked_image_kind(req.matches[3]);
          ImageRelayRequest r;
          {
            PgPool::Lease db = db_->take();
            const std::optional<FleetFillet> f = fleet_fillet(*db, server, uid);
            if (!f) throw NotFound("no fillet " + std::to_string(uid) + " of server " + server);
            if (std::find(f->images.begin(), f->images.end(), kind) == f->images.end())
              throw NotFound("server " + server + " keeps no " + kind + " image of fillet " +
                             std::to_string(uid));
            if (const std::optional<FleetServerRow> row = fleet_server(*db, server))
              r.url = row->http;
          }
          r.server = server;
          r.path = "/api/fillets/" + std::to_string(uid) + "/images/" + kind +
                   (req.get_param_value("raw") == "1" ? "?raw=1" : "");
          r.authorization = req.get_header_value("Authorization");
          r.timeout_s = opt_.image_timeout_s;
          r.ca_file = opt_.servers_ca;
          const RelayedImage got = relay_image(r);
          res.status = got.status;
          if (got.status == 200) res.set_header("Cache-Control", "max-age=3600");
          res.set_content(got.body, got.type.empty() ? "application/octet-stream" : got.type);
        });
}

}  // namespace rangex
