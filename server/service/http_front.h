// What every rangex HTTP endpoint does before its routes, so that rangexd's dashboard and
// the fleet view (rangexd --fleet) guard their doors the same way: TLS from plant.yaml's
// security section, the HttpGate in front of cpp-httplib, the viewer role on every request
// (the dashboard's files too), refusal of hostile requests, errors as JSON with their
// status, and the dashboard's embedded files.
#pragma once
#include <memory>
#include <string>
#include <thread>

#include "core/security_config.h"
#include "service/access_control.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace rangex {

class GatedHttpServer;

struct HttpFront {
  std::unique_ptr<GatedHttpServer> server;
  std::string host;
  int want_port = 0;  // 0: any free one
};

// A gated server for `listen` (host:port), TLS when `security` says so, with `workers`
// workers. Throws Error naming `what` (e.g. "plant.http") and what is wrong.
HttpFront make_http_front(const std::string& listen, const SecurityConfig& security, int workers,
                          const std::string& what);
// Binds (throws Error naming the address when it cannot) and returns the port.
int bind_http_front(HttpFront& f, const std::string& listen, const std::string& what);
// Serves the bound server on a thread of its own, returned once it serves: a stop() that came
// before the listener started would find nothing to stop, and the listener would never return.
std::thread listen_in_background(httplib::Server& s);
// Every request needs the viewer role; hostile requests are refused; handlers' exceptions
// are answered as {"error": ...} with their status (BadRequest 400, NotFound 404, ...).
void guard_http(httplib::Server& s, const AccessControl& access);
// GET / and the dashboard's other files.
void serve_dashboard_files(httplib::Server& s);
// Who sent the request: its verified client certificate, or its token.
Identity identify_request(const AccessControl& access, const httplib::Request& req);

}  // namespace rangex
