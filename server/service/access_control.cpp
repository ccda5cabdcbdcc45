#include "service/access_control.h"

#include <openssl/crypto.h>
#include <strings.h>

#include "store/sha256_hex.h"

namespace rangex {

namespace {

std::string decode_base64(const std::string& in) {
  static const std::string chars =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  int bits = 0, acc = 0;
  for (const char c : in) {
    if (c == '=') break;
    const auto v = chars.find(c);
    if (v == std::string::npos) throw Unauthenticated("Basic credentials are not valid base64");
    acc = (acc << 6) | int(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(char((acc >> bits) & 0xff));
    }
  }
  return out;
}

// The token an Authorization header carries: "Bearer T", or "Basic base64(user:T)" (what a
// browser sends after its login prompt; the user part is not trusted, the token names).
std::string token_of(const std::string& authorization) {
  auto starts = [&](const char* scheme, size_t n) {
    return authorization.size() > n && strncasecmp(authorization.c_str(), scheme, n) == 0;
  };
  if (starts("Bearer ", 7)) return authorization.substr(7);
  if (starts("Basic ", 6)) {
    const std::string pair = decode_base64(authorization.substr(6));
    const auto colon = pair.find(':');
    if (colon == std::string::npos) throw Unauthenticated("Basic credentials lack 'user:token'");
    return pair.substr(colon + 1);
  }
  throw Unauthenticated("the authorization header is neither 'Bearer TOKEN' nor Basic");
}

}  // namespace

Identity AccessControl::identify(const std::string& cert_cn, const std::string& authorization,
                                 const std::string& peer) const {
  if (!authorization.empty()) {
    if (cfg_.tokens.empty())
      throw Unauthenticated("this server takes no bearer tokens (plant.yaml security.tokens)");
    const std::string digest = sha256_hex(token_of(authorization));
    for (const TokenEntry& t : cfg_.tokens)
      if (CRYPTO_memcmp(t.sha256.data(), digest.data(), digest.size()) == 0)
        return {"token:" + t.name, t.role};
    throw Unauthenticated("unknown bearer token (sha256 " + digest.substr(0, 12) +
                          "... is not in plant.yaml security.tokens)");
  }
  if (!cert_cn.empty()) {
    const auto it = cfg_.identities.find(cert_cn);
    // A certificate the CA signed but the plant gives no role: known, and allowed nothing.
    return {"cert:" + cert_cn, it == cfg_.identities.end() ? Role::none : it->second};
  }
  return {"anonymous@" + peer, cfg_.anonymous_role()};
}

void AccessControl::require(const Identity& who, Role needed, const std::string& what) {
  if (who.role >= needed) return;
  if (who.name.rfind("anonymous@", 0) == 0)
    throw Unauthenticated(what + " needs the " + role_name(needed) +
                          " role: present a client certificate or a bearer token");
  throw PermissionDenied(what + " needs the " + role_name(needed) + " role; " + who.name + " has " +
                         (who.role == Role::none
                              ? std::string("no role")
                              : std::string("the ") + role_name(who.role) + " role"));
}

bool is_loopback_host(const std::string& address) {
  std::string host = address;
  if (!host.empty() && host[0] == '[') {  // [v6]:port
    host = host.substr(1, host.find(']') - 1);
  } else if (const auto colon = host.rfind(':');
             colon != std::string::npos && host.find(':') == colon) {
    host = host.substr(0, colon);  // v4 or name with a port
  }
  if (host.rfind("ipv4:", 0) == 0) host = host.substr(5);
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

void check_listen_security(const std::string& address, const SecurityConfig& s,
                           const std::string& what) {
  if (is_loopback_host(address) || s.insecure) return;
  if (!s.tls())
    fail("refusing to serve ", what, " on ", address,
         " without TLS: beyond loopback anyone on the network could read and forge it. Set "
         "security.tls (cert, key), or security.insecure: true to accept the risk");
  if (s.anonymous_role() != Role::none && !s.authenticates())
    fail("refusing to serve ", what, " on ", address,
         " with no authentication: every client "
         "would be ",
         role_name(s.anonymous_role()),
         ". Set security.tls.client_ca with "
         "security.identities, or security.tokens, or security.insecure: true");
}

}  // namespace rangex
