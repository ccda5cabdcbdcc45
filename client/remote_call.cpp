#include "remote_call.h"

#include <cctype>
#include <cstdio>

#include "channel.h"
#include "commands.h"
#include "core/error.h"
#include "rangex/v1/decision_names.h"

namespace rangex::cli {

namespace pb = rangex::v1;

std::set<std::string> remote_options(std::set<std::string> own) {
  own.insert({"server", "config", "ca", "cert", "key", "token-file", "tls-name"});
  return own;
}

namespace {
// TLS and credentials: the options, else RANGEX_CA, RANGEX_CERT, RANGEX_KEY and
// RANGEX_TOKEN or RANGEX_TOKEN_FILE (a token is never an argument: `ps` would show it).
ClientSecurity client_security(const Args& a) {
  ClientSecurity s = ClientSecurity::from_environment();
  s.ca = a.get("ca", s.ca);
  s.cert = a.get("cert", s.cert);
  s.key = a.get("key", s.key);
  s.server_name = a.get("tls-name", "");
  if (a.has("token-file"))
    s.token = ClientSecurity::read_token(a.get("token-file", ""), "--token-file");
  return s;
}
}  // namespace

std::string server_address(const Args& a) {
  std::string addr = a.get("server", "");
  return addr.empty() ? load_config(a.get("config", "")).listen : addr;
}

std::shared_ptr<grpc::Channel> server_channel(const Args& a) {
  return rangex_channel(server_address(a), client_security(a));
}

void check_status(const grpc::Status& s, const char* what) {
  if (s.ok()) return;
  // A plaintext client closed on by a TLS server sees only "Socket closed".
  const char* hint = s.error_code() == grpc::StatusCode::UNAVAILABLE
                         ? "; if rangexd speaks TLS, give its CA (--ca or RANGEX_CA)"
                         : "";
  fail(what, ": ", s.error_message().empty() ? "server unreachable" : s.error_message(), " (",
       int(s.error_code()), ")", hint);
}

std::string decision_text(pb::Decision d) {
  std::string t = decision_name(d);
  if (t.empty()) return "?";
  for (char& c : t) c = c == '_' ? ' ' : char(std::toupper(static_cast<unsigned char>(c)));
  return t;
}

void print_fillet(const pb::FilletResult& f) {
  std::printf("lane %d fillet %-5lld uid %-7lld %-13s", f.lane(), (long long)f.lane_fillet(),
              (long long)f.uid(), decision_text(f.decision()).c_str());
  if (!f.reason().empty()) std::printf(" %s", f.reason().c_str());
  for (const auto& g : f.fragments())
    if (g.kind() == "bone")
      std::printf("  [bone at x %.1f mm, belt %.1f mm, %.1f mm2, z %.1f]", g.x_mm(), g.y_mm(),
                  g.area_mm2(), g.peak_z());
  std::printf("\n");
}

}  // namespace rangex::cli
