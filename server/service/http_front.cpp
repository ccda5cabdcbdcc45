#include "service/http_front.h"

#include <httplib.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <sys/socket.h>

#include <chrono>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/host_port.h"
#include "core/json_text.h"
#include "service/gated_http_server.h"
#include "service/http_params.h"
#include "web_assets.h"

namespace rangex {

using json = nlohmann::json;

namespace {

// The server's certificate and key; with a client CA, client certificates are asked for and
// verified when presented (a browser without one logs in with a token instead).
bool setup_tls(SSL_CTX& ctx, const SecurityConfig& s, std::string& why) {
  auto failed = [&](const std::string& what) {
    char buf[256] = "";
    ERR_error_string_n(ERR_get_error(), buf, sizeof buf);
    why = what + " (" + buf + ")";
    return false;
  };
  SSL_CTX_set_min_proto_version(&ctx, TLS1_2_VERSION);
  // A client may not make the server renegotiate (a handshake's cost, asked for again).
  SSL_CTX_set_options(&ctx, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
  if (SSL_CTX_use_certificate_chain_file(&ctx, s.tls_cert.c_str()) != 1)
    return failed("security.tls.cert: cannot load " + s.tls_cert);
  if (SSL_CTX_use_PrivateKey_file(&ctx, s.tls_key.c_str(), SSL_FILETYPE_PEM) != 1)
    return failed("security.tls.key: cannot load " + s.tls_key);
  if (SSL_CTX_check_private_key(&ctx) != 1)
    return failed("security.tls.key does not match security.tls.cert");
  if (!s.client_ca.empty()) {
    if (SSL_CTX_load_verify_locations(&ctx, s.client_ca.c_str(), nullptr) != 1)
      return failed("security.tls.client_ca: cannot load " + s.client_ca);
    SSL_CTX_set_client_CA_list(&ctx, SSL_load_client_CA_file(s.client_ca.c_str()));
    SSL_CTX_set_verify(&ctx, SSL_VERIFY_PEER, nullptr);
  }
  return true;
}

// The common name of the client's verified certificate ("" without one).
std::string peer_common_name(const httplib::Request& req) {
  if (!req.ssl) return "";
  X509* cert = SSL_get0_peer_certificate(req.ssl);
  if (!cert || SSL_get_verify_result(req.ssl) != X509_V_OK) return "";
  char cn[256] = "";
  if (X509_NAME_get_text_by_NID(X509_get_subject_name(cert), NID_commonName, cn, sizeof cn) <= 0)
    return "";
  return cn;
}

constexpr size_t kMaxHeaders = 100;

// Answers (and returns true for) a request too big to serve: too many headers, or more
// than one range.
bool refuse_hostile(const httplib::Request& req, httplib::Response& res) {
  // cpp-httplib 0.11 bounds each header line (8 kB) but not their number, and serves every
  // part of a multi-range request: 2,600 parts of "bytes=0-" turned a 7.9 kB image into a
  // 248 MB response. No browser or dashboard asks for more than one range.
  if (req.headers.size() > kMaxHeaders) {
    res.status = 431;
    res.set_content(
        json_dump(json{{"error", "more than " + std::to_string(kMaxHeaders) + " request headers (" +
                                     std::to_string(req.headers.size()) + ")"}}),
        "application/json");
    return true;
  }
  if (req.ranges.size() > 1) {
    const size_t parts = req.ranges.size();
    // Cleared, or httplib would still cut the refusal into those parts.
    const_cast<httplib::Request&>(req).ranges.clear();
    res.status = 416;
    res.set_content(
        json_dump(json{{"error", "multi-range requests are not served (" + std::to_string(parts) +
                                     " ranges); ask for one range"}}),
        "application/json");
    return true;
  }
  return false;
}

}  // namespace

HttpFront make_http_front(const std::string& listen, const SecurityConfig& security, int workers,
                          const std::string& what) {
  HttpFront f;
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos)
    fail(what, " '", listen, "' must be host:port (port 0: any free one)");
  f.host = listen.substr(0, colon);
  f.want_port = port_of(listen);
  if (f.want_port < 0) fail(what, " '", listen, "': the port must be a number 0..65535");
  GateOptions g;
  g.workers = workers;
  SSL_CTX* tls = nullptr;
  if (security.tls()) {
    std::string why;
    tls = SSL_CTX_new(TLS_server_method());
    if (!tls || !setup_tls(*tls, security, why)) {
      if (tls) SSL_CTX_free(tls);
      fail(what, ": TLS: ", why.empty() ? "cannot set up" : why);
    }
  }
  f.server = std::make_unique<GatedHttpServer>(g, tls);
  // httplib binds with SO_REUSEPORT, which lets a second server on this port start and take
  // half of the browsers' connections. SO_REUSEADDR alone still rebinds at once after a
  // restart left connections in TIME_WAIT, and refuses a port that another one listens on.
  f.server->set_socket_options([](socket_t sock) {
    const int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  f.server->set_read_timeout(10, 0);
  f.server->set_write_timeout(10, 0);
  return f;
}

int bind_http_front(HttpFront& f, const std::string& listen, const std::string& what) {
  const int port = f.want_port == 0
                       ? f.server->bind_to_any_port(f.host)
                       : (f.server->bind_to_port(f.host, f.want_port) ? f.want_port : -1);
  if (port <= 0) fail(what, ": cannot listen on ", listen, " (in use, or no such address)");
  return port;
}

std::thread listen_in_background(httplib::Server& s) {
  std::thread t([&s] { s.listen_after_bind(); });
  for (int k = 0; k < 500 && !s.is_running(); ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  return t;
}

Identity identify_request(const AccessControl& access, const httplib::Request& req) {
  return access.identify(peer_common_name(req), req.get_header_value("Authorization"),
                         req.remote_addr);
}

void guard_http(httplib::Server& s, const AccessControl& access) {
  // Every request, before routing: the dashboard's files too, so that a page never loads
  // without its data.
  s.set_pre_routing_handler([&access](const httplib::Request& req, httplib::Response& res) {
    if (refuse_hostile(req, res)) return httplib::Server::HandlerResponse::Handled;
    try {
      AccessControl::require(identify_request(access, req), Role::viewer, "reading the dashboard");
      return httplib::Server::HandlerResponse::Unhandled;
    } catch (const Unauthenticated& e) {
      res.status = 401;
      res.set_header("WWW-Authenticate", "Basic realm=\"rangex\", charset=\"UTF-8\"");
      res.set_content(json_dump(json{{"error", e.what()}}), "application/json");
    } catch (const PermissionDenied& e) {
      res.status = 403;
      res.set_content(json_dump(json{{"error", e.what()}}), "application/json");
    }
    return httplib::Server::HandlerResponse::Handled;
  });
  s.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
        std::string msg = "internal error";
        int status = 500;
        try {
          std::rethrow_exception(ep);
        } catch (const BadRequest& e) {
          msg = e.what(), status = 400;
        } catch (const NotFound& e) {
          msg = e.what(), status = 404;
        } catch (const Unauthenticated& e) {
          msg = e.what(), status = 401;
          res.set_header("WWW-Authenticate", "Basic realm=\"rangex\", charset=\"UTF-8\"");
        } catch (const PermissionDenied& e) {
          msg = e.what(), status = 403;
        } catch (const FailedPrecondition& e) {
          msg = e.what(), status = 409;
        } catch (const Unavailable& e) {
          msg = e.what(), status = 503;
        } catch (const std::exception& e) {
          msg = e.what();
        }
        res.status = status;
        res.set_content(json_dump(json{{"error", msg}}), "application/json");
      });
}

void serve_dashboard_files(httplib::Server& s) {
  for (const WebAsset& a : kWebAssets) {
    const std::string path = std::string("/") + (std::string(a.path) == "index.html" ? "" : a.path);
    s.Get(path, [a](const httplib::Request&, httplib::Response& res) {
      res.set_content(a.body, a.size, a.type);
      res.set_header("Cache-Control", "no-cache");
    });
  }
}

}  // namespace rangex
