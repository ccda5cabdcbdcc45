// What an operator does to a lane from the dashboard: POST /api/lanes/L/verification starts a
// verification run, as gRPC StartVerification does, with the operator role. A browser on
// another site cannot make one: the body must be JSON (a plain form cannot send that without
// this server's consent), and an Origin or Sec-Fetch-Site header, when sent, must be this
// server's.
#include <httplib.h>

#include "core/error.h"
#include "core/json_text.h"
#include "service/http_json.h"
#include "service/http_params.h"
#include "service/http_server.h"

namespace rangex {

using json = nlohmann::json;

namespace {

void answer(httplib::Response& res, int status, const std::string& error) {
  res.status = status;
  res.set_content(json_dump(json{{"error", error}}), "application/json");
}

}  // namespace

// "" when the request may act; otherwise why not (answered 403, or 415 for the body's type).
std::string HttpServer::cross_site(const httplib::Request& req) const {
  if (req.get_header_value("Content-Type").rfind("application/json", 0) != 0)
    return "the body must be JSON (Content-Type: application/json)";
  if (req.get_header_value("Sec-Fetch-Site") == "cross-site")
    return "a request from another site is refused (Sec-Fetch-Site: cross-site)";
  if (req.has_header("Origin")) {
    const std::string origin = req.get_header_value("Origin");
    const std::string mine =
        std::string(tls() ? "https://" : "http://") + req.get_header_value("Host");
    if (origin != mine)
      return "a request from origin '" + origin + "' is refused (this dashboard is " + mine + ")";
  }
  return "";
}

void HttpServer::lane_action_routes(httplib::Server& s) {
  // Refusals go to the server's exception handler (401, 403, 400, 404, 409).
  s.Post(R"(/api/lanes/(\d+)/verification)",
         [this](const httplib::Request& req, httplib::Response& res) {
           const Identity who = identify(req);
           AccessControl::require(who, Role::operator_, "starting a verification");
           if (const std::string why = cross_site(req); !why.empty())
             return answer(res, why.rfind("the body", 0) == 0 ? 415 : 403, why);
           VerificationRequest r = verification_body(req.body);
           r.lane = int(parse_int("lane", req.matches[1], 0, 1 << 20));
           LaneState l;
           try {
             l = engine_.start_verification(r, who.name);
           } catch (const NotFound&) {
             throw;
           } catch (const FailedPrecondition&) {
             throw;
           } catch (const Error& e) {
             throw BadRequest(e.what());  // a value out of range: the request's
           }
           send_json(res, {{"lane", lane_json(l, history_, engine_.backend().name)}});
         });
}

}  // namespace rangex
