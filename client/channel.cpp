#include "channel.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace rangex {

namespace {

std::string read_file(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(what, ": cannot read ", path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

}  // namespace

ClientSecurity ClientSecurity::from_environment() {
  ClientSecurity s;
  s.ca = env("RANGEX_CA");
  s.cert = env("RANGEX_CERT");
  s.key = env("RANGEX_KEY");
  s.token = env("RANGEX_TOKEN");
  if (s.token.empty() && !env("RANGEX_TOKEN_FILE").empty())
    s.token = read_token(env("RANGEX_TOKEN_FILE"), "RANGEX_TOKEN_FILE");
  return s;
}

std::string ClientSecurity::read_token(const std::string& path, const char* what) {
  const std::string text = read_file(path, what);
  return trimmed(text.substr(0, text.find('\n')));
}

std::shared_ptr<grpc::Channel> rangex_channel(const std::string& address, const ClientSecurity& sec,
                                              int keepalive_ms) {
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(64 << 20);
  args.SetMaxReceiveMessageSize(64 << 20);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, keepalive_ms);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 5000);
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);  // keep pinging a quiet connection
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  if (sec.ca.empty()) {
    if (!sec.cert.empty() || !sec.token.empty())
      fail(
          "a client certificate or token is sent only over TLS: give the server's CA "
          "(--ca or RANGEX_CA)");
    return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
  }
  if (sec.cert.empty() != sec.key.empty()) fail("a client certificate needs both --cert and --key");
  grpc::SslCredentialsOptions o;
  o.pem_root_certs = read_file(sec.ca, "--ca");
  if (!sec.cert.empty()) {
    o.pem_cert_chain = read_file(sec.cert, "--cert");
    o.pem_private_key = read_file(sec.key, "--key");
  }
  if (!sec.server_name.empty()) args.SetSslTargetNameOverride(sec.server_name);
  std::shared_ptr<grpc::ChannelCredentials> creds = grpc::SslCredentials(o);
  // Sent with every call; gRPC sends call credentials over secure channels only.
  if (!sec.token.empty())
    creds = grpc::CompositeChannelCredentials(creds, grpc::AccessTokenCredentials(sec.token));
  return grpc::CreateCustomChannel(address, creds, args);
}

bool worth_reconnecting(const grpc::Status& s) {
  switch (s.error_code()) {
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::CANCELLED:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
    case grpc::StatusCode::UNKNOWN:
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::ABORTED:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return true;
    default:
      return false;
  }
}

}  // namespace rangex
