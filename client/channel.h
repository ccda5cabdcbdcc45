// The client's channel to rangexd: keepalive and reconnect backoff, and, when the server
// speaks TLS, its CA, an optional client certificate and an optional bearer token.
#pragma once
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

namespace rangex {

struct ClientSecurity {
  std::string ca;           // PEM file of the CA that signed rangexd's certificate: TLS on
  std::string cert, key;    // PEM files of this client's certificate and key (mTLS)
  std::string token;        // sent as "authorization: Bearer TOKEN" (TLS only)
  std::string server_name;  // the name to check the server's certificate against

  // RANGEX_CA, RANGEX_CERT, RANGEX_KEY, RANGEX_TOKEN (or RANGEX_TOKEN_FILE): what command-line
  // options do not set.
  static ClientSecurity from_environment();
  // A token file's first line (throws Error naming the option when it cannot be read).
  static std::string read_token(const std::string& path, const char* what);
};

// How often a rangex client pings an idle connection (gRPC keepalive), without calls too, so
// that a dead server is noticed. Twice the least interval rangexd accepts
// (ServerOptions::min_ping_interval_ms): a client that pings faster is cut off with GOAWAY
// "too_many_pings", a quiet subscription with it.
constexpr int kClientKeepaliveMs = 10000;

// Throws Error when the security options are inconsistent or a file cannot be read.
// keepalive_ms: other than kClientKeepaliveMs only where a test shortens time.
std::shared_ptr<grpc::Channel> rangex_channel(const std::string& address,
                                              const ClientSecurity& security = {},
                                              int keepalive_ms = kClientKeepaliveMs);

// A call that ended so is worth making again once connected: the server went away, restarted,
// was stopping, or shed load (gRPC cuts streams when its memory quota is full,
// server.grpc_memory_mb, whichever stream made it so). A refusal of the caller or of what it
// asked (a role, an argument) is not.
bool worth_reconnecting(const grpc::Status& s);

// A unary call that cannot hang a client: a server that does not answer in 15 s is reported
// as such.
struct UnaryCall : grpc::ClientContext {
  UnaryCall() { set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(15)); }
};

}  // namespace rangex
