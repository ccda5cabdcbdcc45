#include "service/gated_http_server.h"

#include <fcntl.h>
#include <openssl/ssl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <csignal>

#include "service/plain_connection.h"
#include "service/request_end.h"
#include "service/tls_connection.h"

namespace rangex {

namespace {

thread_local int t_fd = -1;

}  // namespace

GatedHttpServer::GatedHttpServer(GateOptions opt, ssl_ctx_st* tls)
    : tls_(tls),
      max_body_(opt.max_body_bytes),
      gate_(std::make_unique<HttpGate>(
          opt, [this](GateConnection& c, std::string& head) { return serve(c, head); })) {
  // Accepting is all that httplib's own pool still does: a few threads are plenty.
  new_task_queue = [] { return new httplib::ThreadPool(2); };
  // OpenSSL writes to the socket without MSG_NOSIGNAL: a client gone mid-answer must not
  // end the server.
  if (tls_) std::signal(SIGPIPE, SIG_IGN);
}

GatedHttpServer::~GatedHttpServer() {
  gate_->stop();
  if (tls_) SSL_CTX_free(tls_);
}

int GatedHttpServer::current_fd() {
  return t_fd;
}

bool GatedHttpServer::process_and_close_socket(socket_t sock) {
  if (!tls_) {
    gate_->admit(std::make_unique<PlainConnection>(sock));
    return true;
  }
  SSL* ssl = SSL_new(tls_);
  if (!ssl) {
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
    return false;
  }
  // Non-blocking from here on: the gate's one thread steps every handshake.
  ::fcntl(sock, F_SETFL, ::fcntl(sock, F_GETFL) | O_NONBLOCK);
  SSL_set_fd(ssl, sock);
  SSL_set_accept_state(ssl);
  gate_->admit(std::make_unique<TlsConnection>(sock, ssl));
  return true;
}

bool GatedHttpServer::serve(GateConnection& c, std::string& head) {
  // A body over the gate's bound (or sent chunked) was not waited for: refused unread, as a
  // worker would otherwise wait for it (a slow body is the slow head's twin).
  if (announced_body(head) > max_body_) {
    const std::string body = "{\"error\":\"a request body is at most " + std::to_string(max_body_) +
                             " bytes, with its Content-Length\"}";
    c.refuse(
        "HTTP/1.1 413 Payload Too Large\r\nConnection: close\r\nContent-Type: "
        "application/json\r\nContent-Length: " +
        std::to_string(body.size()) + "\r\n\r\n" + body);
    return false;
  }
  const std::unique_ptr<httplib::Stream> strm =
      c.stream(head, read_timeout_sec_, write_timeout_sec_);
  bool closed = false;
  t_fd = c.fd();
  SSL* ssl = c.tls();
  const bool ok =
      process_request(*strm, false, closed, [ssl](httplib::Request& req) { req.ssl = ssl; });
  t_fd = -1;
  return ok && !closed && is_running();
}

}  // namespace rangex
